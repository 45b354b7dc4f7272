"""Errors the engine raises with a message meant for the user (status bar, console, CLI)."""


class RadTRError(Exception):
    """Base class: the message names the object, patch or file and what is wrong."""


class SceneError(RadTRError):
    """The scene cannot be solved as it is (bad values, nothing emits, no geometry)."""


class InputFileError(RadTRError):
    """A file given to RadTR cannot be read as what it claims to be."""


class Cancelled(RadTRError):
    """The user cancelled; nothing was changed."""


class GPUUnavailable(RadTRError):
    """No GPU drawing context could be had for a GPU form-factor method."""


class SettingsError(RadTRError, ValueError):
    """A setting out of range or unknown (names the setting and the value)."""
