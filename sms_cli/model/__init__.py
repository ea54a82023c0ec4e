"""URDF + mission → SystemModel (Pinocchio free-flyer model with wheels, springs, modes, payloads)."""

from __future__ import annotations


def compile_system(loaded):
    """Compile a loaded mission into a ``SystemModel`` (see ``sms_cli.model.compiler``)."""
    from sms_cli.model.compiler import compile_system as _compile

    return _compile(loaded)


__all__ = ["compile_system"]
