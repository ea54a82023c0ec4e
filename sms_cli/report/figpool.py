"""Figures drawn on worker processes while the caller draws too (issue #19).

Matplotlib draws one figure on one core; a command that writes many figures (``sms analyze``: 22)
hands them to :class:`FigurePool` as jobs returning PNG bytes (``sms_cli.analysis.plots.clouds``,
``histograms_png``, …), which the caller writes in its own order: the same bytes whichever process
drew a figure (``sms_cli.workers``). Its workers import matplotlib and draw a warm-up figure as soon
as they start. How many: ``SMS_FIGURE_WORKERS`` (0: every figure in the calling process), else one
less than the usable cores, at most ``sms_cli.workers.MAX_WORKERS``.
"""

from __future__ import annotations

from sms_cli.workers import WorkerPool
from sms_cli.workers import default_workers as _default_workers

PRELOAD = ("sms_cli.report.figstyle:warm_up", "sms_cli.analysis.plots")


def default_workers() -> int:
    """Figure workers started when not told (see the module's docstring)."""
    return _default_workers("SMS_FIGURE_WORKERS")


class FigurePool(WorkerPool):
    """A :class:`sms_cli.workers.WorkerPool` of figure workers (``workers`` None: :func:`default_workers`)."""

    def __init__(self, workers: int | None = None):
        super().__init__(default_workers() if workers is None else workers, preload=PRELOAD)
