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


def describe(exc: BaseException) -> str:
    """'Type: message (file:line)' of the innermost frame, for a one-line report."""
    import traceback
    from pathlib import Path

    tb = traceback.extract_tb(exc.__traceback__)
    where = f" ({Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
    return f"{type(exc).__name__}: {exc}{where}"


def user_message(exc: BaseException) -> str:
    """What to tell the user about ``exc``: a RadTRError's own message, anything else described."""
    if isinstance(exc, RadTRError):
        return str(exc)
    if isinstance(exc, MemoryError):
        return "out of memory; lower the resolution, rays or patch count"
    return f"unexpected error: {describe(exc)}"
