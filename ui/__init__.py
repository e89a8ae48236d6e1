"""User interface: the settings stored on the scene and the Render Properties panels."""
