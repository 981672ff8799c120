"""The exceptions troupe raises: one class per C status code (`troupe_status`), all under
`TroupeError`, so a program catches what it can handle without parsing messages.

    try:
        model = troupe.Model(path)
    except troupe.ModelError as e:      # TROUPE_ERR_MODEL: not a bundle troupe can load
        print(e.status, e.name, e.message)

Arguments of the wrong Python type raise `TypeError` before the library is called; values the
library refuses raise these. `InvalidArgument` and `ShapeMismatch` are also `ValueError`s, and
`BufferTooSmall` too, as Python code that catches `ValueError` for a bad value would expect;
`IoError` is also an `OSError`. An array of the wrong shape raises `ShapeMismatch` whether the
binding or the library notices it, and text where numbers are expected a `TypeError`.
"""

from __future__ import annotations

from typing import TypeVar

T = TypeVar("T")

__all__ = [
    "TroupeError", "NullArgument", "InvalidArgument", "ShapeMismatch", "BufferTooSmall", "IoError",
    "ModelError", "InferenceError", "Poisoned", "Panicked", "Busy", "Cancelled", "Unsupported",
]


class TroupeError(Exception):
    """A troupe call failed. `status` is the `TROUPE_ERR_*` code, `name` its symbolic name and
    `message` the library's explanation (`troupe_last_error_message`)."""

    status: int = -1
    name: str = "TROUPE_ERR_UNKNOWN"

    def __init__(self, message: str, status: int | None = None, name: str | None = None):
        if status is not None:
            self.status = status
        if name is not None:
            self.name = name
        self.message = message
        super().__init__(f"{self.name}: {message}")


class NullArgument(TroupeError):
    """TROUPE_ERR_NULL_ARG: a required pointer was NULL (a binding bug if raised from Python)."""

    status, name = 1, "TROUPE_ERR_NULL_ARG"


class InvalidArgument(TroupeError, ValueError):
    """TROUPE_ERR_INVALID_ARG: a value out of range, non-finite or unknown (the message says which)."""

    status, name = 2, "TROUPE_ERR_INVALID_ARG"


class ShapeMismatch(TroupeError, ValueError):
    """TROUPE_ERR_SHAPE: an array of the wrong size for the model."""

    status, name = 3, "TROUPE_ERR_SHAPE"


class BufferTooSmall(TroupeError, ValueError):
    """TROUPE_ERR_BUFFER_TOO_SMALL: an output buffer could not hold the result."""

    status, name = 4, "TROUPE_ERR_BUFFER_TOO_SMALL"


class IoError(TroupeError, OSError):
    """TROUPE_ERR_IO: a file could not be read or written (also an `OSError`, as Python's own
    file errors are)."""

    status, name = 5, "TROUPE_ERR_IO"


class ModelError(TroupeError):
    """TROUPE_ERR_MODEL: the bundle is corrupt, of another version, or not one troupe can load."""

    status, name = 6, "TROUPE_ERR_MODEL"


class InferenceError(TroupeError):
    """TROUPE_ERR_INFERENCE: a network failed or produced non-finite values; the session's state
    is as it was before the call."""

    status, name = 7, "TROUPE_ERR_INFERENCE"


class Poisoned(TroupeError):
    """TROUPE_ERR_POISONED: an earlier panic left this object unusable until it is reset."""

    status, name = 8, "TROUPE_ERR_POISONED"


class Panicked(TroupeError):
    """TROUPE_ERR_PANIC: the library caught an internal panic (a bug in troupe: please report)."""

    status, name = 9, "TROUPE_ERR_PANIC"


class Busy(TroupeError):
    """TROUPE_ERR_BUSY: another thread is using this session."""

    status, name = 10, "TROUPE_ERR_BUSY"


class Cancelled(TroupeError):
    """TROUPE_ERR_CANCELLED: a progress callback asked the call to stop."""

    status, name = 11, "TROUPE_ERR_CANCELLED"


class Unsupported(TroupeError):
    """TROUPE_ERR_UNSUPPORTED: the bundle's family does not offer this call."""

    status, name = 12, "TROUPE_ERR_UNSUPPORTED"


_BY_STATUS = {cls.status: cls for cls in TroupeError.__subclasses__()}


def from_status(status: int, message: str, name: str) -> TroupeError:
    """The exception for a status code; a code this package does not know (a newer library)
    becomes a plain `TroupeError` carrying it."""
    cls = _BY_STATUS.get(status)
    return cls(message) if cls is not None else TroupeError(message, status, name)


def expect_type(value: T, expected: type, what: str) -> T:
    """`value` if it is an `expected`; else a `TypeError` naming the type wanted and the one
    given (a tuple where a `JointsFormat` is expected, say)."""
    if not isinstance(value, expected):
        raise TypeError(f"{what} must be a {expected.__module__}.{expected.__qualname__}, "
                        f"got {type(value).__name__}")
    return value
