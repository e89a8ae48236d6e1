"""Errors the user sees. Each message names the object and the problem."""


class SceneError(ValueError):
    """The scene (or a file holding one) cannot be baked as it is."""


class BakeCancelled(RuntimeError):
    """The bake was cancelled; nothing was written."""
