"""Optional PDF of a report through headless Chromium (``--print-to-pdf``), written atomically."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from sms_cli.errors import InputError, Location, Problem
from sms_cli.results import atomic_path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def find_browser() -> str | None:
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


def print_pdf(html: Path, target: Path | None = None, timeout: float = 120.0) -> Path:
    """Print ``html`` to ``target`` (default: same name, ``.pdf``)."""
    browser = find_browser()
    if browser is None:
        raise InputError(problems=[Problem("no PDF engine: chromium is not installed",
                                           hint="install it (Debian: apt-get install chromium) or open the HTML and print it")])
    target = Path(target) if target is not None else Path(html).with_suffix(".pdf")
    with tempfile.TemporaryDirectory(prefix="sms-chromium-") as profile, atomic_path(target) as tmp:
        cmd = [browser, *FLAGS, f"--user-data-dir={profile}", "--no-pdf-header-footer",
               f"--print-to-pdf={tmp}", Path(html).resolve().as_uri()]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise InputError(problems=[Problem(f"chromium did not finish printing the PDF within {timeout:.0f} s",
                                               Location(html), hint="open the HTML and print it from a browser")]) from None
        if proc.returncode != 0 or tmp.stat().st_size == 0:
            raise InputError(problems=[Problem(f"chromium could not print it (exit {proc.returncode}): "
                                               f"{proc.stderr.strip()[-400:]}", Location(html),
                                               hint="open the HTML and print it from a browser")])
    return target
