"""Optional PDF of a report through headless Chromium (``--print-to-pdf``), written atomically.

The page set-up is the report's print stylesheet: A4 (``@page``), a title page with the verdict, page
numbers in the footer, tables that wrap to the page width. ``paper`` prints on another CSS page size.
"""

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


PAPERS = ("A4", "A3", "A5", "letter", "legal")


def print_pdf(html: Path, target: Path | None = None, timeout: float = 120.0, paper: str = "A4") -> Path:
    """Print ``html`` to ``target`` (default: same name, ``.pdf``) on ``paper`` (one of :data:`PAPERS`)."""
    if paper not in PAPERS:
        raise InputError(problems=[Problem(f"unknown paper size '{paper}'", hint="one of " + ", ".join(PAPERS))])
    browser = find_browser()
    if browser is None:
        raise InputError(problems=[Problem("no PDF engine: chromium is not installed",
                                           hint="install it (Debian: apt-get install chromium) or open the HTML and print it")])
    target = Path(target) if target is not None else Path(html).with_suffix(".pdf")
    with tempfile.TemporaryDirectory(prefix="sms-chromium-") as profile, atomic_path(target) as tmp:
        source = Path(html).resolve()
        if paper != "A4":  # the report's stylesheet says A4: a copy that says otherwise
            text = source.read_text(encoding="utf-8")
            source = Path(profile) / "report.html"
            source.write_text(text.replace("</head>", f"<style>@page {{ size: {paper}; }}</style></head>", 1), encoding="utf-8")
        cmd = [browser, *FLAGS, f"--user-data-dir={profile}", "--no-pdf-header-footer",
               f"--print-to-pdf={tmp}", source.as_uri()]
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
