"""One mapping from a failure to the contract's exit code and message, for every command and for
each stage of ``sms run``: sms's own errors as they render; a file-system failure as exit 2 (3 for a
full disk) naming the path; a numerical failure from numpy as exit 3 with a fix; anything else is a
bug (exit 4), the only message that names an exception class."""

from __future__ import annotations

from typing import Sequence

from sms_cli.errors import EXIT_INTERNAL, EXIT_NUMERICAL, SmsError

_NUMERIC = {"LinAlgError", "FloatingPointError"}


def interrupted(exc: BaseException) -> bool:
    """The exception is, or was caused by, an interrupt (SIGINT/SIGTERM as ``KeyboardInterrupt``). Python
    wraps an interrupt that lands while a class is being created, e.g. during a module's first import
    (``__set_name__`` of a dataclass field), in a RuntimeError whose cause is the interrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def failure(exc: BaseException, outputs: Sequence = ()) -> tuple[int, str]:
    """(exit code, message without the 'error: ' prefix) of an exception a command did not handle."""
    if isinstance(exc, SmsError):
        return exc.exit_code, exc.render()
    if isinstance(exc, OSError):
        from sms_cli.outputs import from_os_error

        mapped = from_os_error(exc, outputs)
        if mapped is not None:
            return mapped.exit_code, mapped.render()
    if type(exc).__name__ in _NUMERIC:
        return EXIT_NUMERICAL, (f"numerical failure: {exc}\n    fix: look for an extreme or degenerate value in the "
                                "mission or the URDF (a zero mass, an inertia off by orders of magnitude); --debug "
                                "shows where it happened")
    return EXIT_INTERNAL, ("internal error (a bug in sms; please report it, run with --debug for the traceback): "
                           f"{type(exc).__name__}: {exc}")
