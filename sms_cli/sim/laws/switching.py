"""Smoothing names shared by the sliding-mode laws: tanh(gain·σ) (boundary layer) or sign(σ)."""

from __future__ import annotations

SMOOTHINGS = ("tanh", "sign")


def check_smoothing(smoothing: str) -> str:
    """Validate a sliding-mode smoothing name."""
    if smoothing not in SMOOTHINGS:
        raise ValueError("smoothing is 'tanh' or 'sign'")
    return smoothing

