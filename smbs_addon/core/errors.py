"""Errors the user sees. Each message names the object and the problem."""


class SceneError(ValueError):
    """The scene (or a file holding one) cannot be baked as it is."""


class BakeCancelled(RuntimeError):
    """The bake was cancelled; nothing was written. signum: the signal that stopped it (core/signals.py),
    0 for a cancel by the caller."""

    def __init__(self, message: str = "bake cancelled", signum: int = 0):
        super().__init__(message)
        self.signum = signum


class WriteError(OSError):
    """An output could not be written whole; the previous file (if any) is unchanged, and the
    message says where the result was kept instead (io.exr.save_outputs)."""
