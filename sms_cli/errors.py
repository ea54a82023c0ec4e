"""The error contract: every failure a user can cause maps to one exception and one exit code.

Exit codes (documented in the README and ``sms --help``):
  0 ok · 1 requirements not met · 2 invalid input or usage · 3 numerical failure
  (infeasible synthesis, diverged simulation, singular model) or the disk is full ·
  4 internal error (a bug in sms) · 130 interrupted (SIGINT or SIGTERM).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

EXIT_OK = 0
EXIT_REQUIREMENTS = 1
EXIT_INPUT = 2
EXIT_NUMERICAL = 3
EXIT_INTERNAL = 4  # a bug in sms: the only exit code a user's input must never cause
EXIT_INTERRUPTED = 130


@dataclass
class Location:
    """A place in an input file (1-based line and column; 0 when unknown)."""

    file: Path | str
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        s = str(self.file)
        if self.line:
            s += f":{self.line}"
            if self.column:
                s += f":{self.column}"
        return s


@dataclass
class Problem:
    """One finding about an input: where, what, and how to fix it."""

    message: str
    location: Location | None = None
    field: str = ""
    hint: str = ""
    lint: bool = False  # a warning that ``strict`` (sms compile --strict, robot.strict) turns into an error

    def render(self) -> str:
        head = f"{self.location}: " if self.location else ""
        where = f"{self.field}: " if self.field else ""
        tail = f"\n    fix: {self.hint}" if self.hint else ""
        return f"{head}{where}{self.message}{tail}"


class SmsError(Exception):
    """Base class of the errors sms reports to users without a traceback."""

    exit_code = EXIT_INPUT

    def __init__(self, message: str = "", problems: list[Problem] | None = None):
        self.problems = list(problems or [])
        super().__init__(message or "; ".join(p.message for p in self.problems))

    def render(self) -> str:
        lines = [str(self.args[0])] if self.args and self.args[0] and not self.problems else []
        if self.problems:
            if self.args and self.args[0] and len(self.problems) > 1:
                lines.append(str(self.args[0]))
            lines.extend(p.render() for p in self.problems)
        return "\n".join(lines)


class InputError(SmsError):
    """Invalid mission file, URDF, command-line usage or requirement (exit 2)."""

    exit_code = EXIT_INPUT


class NumericalError(SmsError):
    """Infeasible synthesis, diverged simulation, singular model (exit 3)."""

    exit_code = EXIT_NUMERICAL


class RequirementsNotMet(SmsError):
    """At least one requirement failed (exit 1)."""

    exit_code = EXIT_REQUIREMENTS


@dataclass
class Warnings:
    """Non-fatal findings collected while compiling; shown by ``sms compile``."""

    items: list[Problem] = field(default_factory=list)

    def add(self, message: str, location: Location | None = None, field: str = "", hint: str = "",
            lint: bool = False) -> None:
        self.items.append(Problem(message, location, field, hint, lint))

    def lint(self) -> list[Problem]:
        """The findings that strict mode refuses."""
        return [p for p in self.items if p.lint]

    def __iter__(self):
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)
