"""``sms report``: a self-contained HTML file that renders in headless Chromium without console
errors, with every embedded plot decoded; deterministic bytes; only sections whose data exist.

Chromium comes from Debian's package (``apt-get install -y chromium``); the browser tests are
skipped, with that reason, only where /usr/bin/chromium is absent.
"""

from __future__ import annotations

import base64
import io
import json
import re
import subprocess
import tempfile
from pathlib import Path

import pytest

from conftest import MISSIONS, run_cli

CHROMIUM = Path("/usr/bin/chromium")
needs_chromium = pytest.mark.skipif(not CHROMIUM.exists(), reason="chromium is not installed "
                                    "(Debian: apt-get update && apt-get install -y chromium)")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PROBE = """<script>
window.__errors = [];
window.addEventListener('error', function (e) {
  window.__errors.push(String(e.message || ('resource failed: ' + ((e.target && (e.target.src || e.target.href)) || '?'))).slice(0, 160));
}, true);
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var p = document.createElement('pre'); p.id = '__probe';
  p.textContent = JSON.stringify({errors: window.__errors, images: imgs.length,
    broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).length,
    height: document.body.scrollHeight});
  document.body.appendChild(p);
});
</script>"""


def chromium(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory(prefix="sms-test-chromium-") as profile:
        return subprocess.run([str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", *args], capture_output=True,
                              text=True, timeout=timeout)


def browser_check(report: Path, tmp_path: Path) -> tuple[dict, Path]:
    """Load the report (with an error probe injected) → probe result; screenshot of the real file."""
    html = report.read_text(encoding="utf-8")
    probed = tmp_path / "probed.html"
    probed.write_text(html.replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    r = chromium("--enable-logging=stderr", "--v=0", "--virtual-time-budget=10000", "--dump-dom", probed.as_uri())
    m = re.search(r'<pre id="__probe">(.*?)</pre>', r.stdout, re.S)
    assert m, f"probe did not run: {r.stderr[-2000:]}"
    probe = json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    probe["console"] = [line for line in r.stderr.splitlines() if ":CONSOLE" in line]
    shot = tmp_path / "screenshot.png"
    chromium("--hide-scrollbars", "--window-size=1280,10000", f"--screenshot={shot}", report.as_uri())
    return probe, shot


def shared_slew_results(tmp_path_factory) -> Path:
    """Caldera S1 (compile + analyze + synthesize + simulate): every kind of plot but budget, in ~15 s;
    run once per session for the report modules (they only read it)."""
    out = tmp_path_factory.getbasetemp() / "shared-report" / "caldera_s1_slew"
    if not (out / "report.html").is_file():
        r = run_cli("run", MISSIONS / "caldera_s1_slew.yaml", "-o", out, "--no-progress")
        assert r.exit_code == 0, r.output
    return out


@pytest.fixture(scope="module")
def slew_results(tmp_path_factory) -> Path:
    return shared_slew_results(tmp_path_factory)


def _images(html: str) -> list[bytes]:
    return [base64.b64decode(b) for b in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


def test_report_is_self_contained_and_complete(slew_results):
    html = (slew_results / "report.html").read_text(encoding="utf-8")
    from PIL import Image

    imgs = _images(html)
    # robot + 11 analysis plots + 3 stage plots + wheel momentum + joint tracking + EE path
    assert len(imgs) >= 16
    for data in imgs:
        with Image.open(io.BytesIO(data)) as im:
            im.load()
            assert im.size[0] >= 300 and im.size[1] >= 200
    # nothing fetched from outside: no external URLs in src/href, no scripts
    assert not re.search(r'(src|href)="(?!data:|#)', html)
    assert "<script" not in html
    results = json.loads((slew_results / "results.json").read_text())
    titles = {"compile": "Mission and model", "analysis": "Workspace and kinematic indices", "budget": "ΔV and propellant budget",
              "synthesis": "Gains and closed-loop poles", "simulate": "Nonlinear simulation"}
    assert "budget" not in results and {"compile", "analysis", "simulate"} <= set(results)
    for section, title in titles.items():  # a section exactly when its data exist
        assert (f">{title}</h2>" in html) == (section in results), title
    assert "<h2>Provenance</h2>" in html
    run = results["run"]
    assert run["mission_sha256"] in html and run["date"] in html


def test_report_bytes_are_deterministic(slew_results, tmp_path):
    a, b = tmp_path / "a.html", tmp_path / "b.html"
    assert run_cli("report", slew_results, "-o", a).exit_code == 0
    assert run_cli("report", slew_results, "-o", b).exit_code == 0
    assert a.read_bytes() == b.read_bytes()


def test_budget_only_report_and_errors(tmp_path):
    out = tmp_path / "geo"
    assert run_cli("run", MISSIONS / "hipparcos_geo.yaml", "-o", out, "--no-report").exit_code == 0
    r = run_cli("report", out)
    assert r.exit_code == 0, r.output
    html = (out / "report.html").read_text()
    assert "ΔV and propellant budget" in html and "Requirement verdicts" in html and "4/4 requirements met" in html
    assert "Nonlinear simulation" not in html and "Mission and model" not in html
    assert "Reach AR6 upper stage" in html and len(_images(html)) == 2
    r = run_cli("report", tmp_path / "nothing")
    assert r.exit_code == 2 and "no results.json" in r.output


@needs_chromium
def test_report_renders_in_chromium_without_errors(slew_results, tmp_path):
    probe, shot = browser_check(slew_results / "report.html", tmp_path)
    assert probe["errors"] == [] and probe["console"] == [], probe
    assert probe["images"] >= 16 and probe["broken"] == 0, probe
    assert probe["height"] > 5000
    _assert_shows_plots(shot)


def _assert_shows_plots(shot: Path) -> None:
    """The page shows drawn content: many coloured pixels (plots, maps, drawings), not only text."""
    import numpy as np
    from PIL import Image

    with Image.open(shot) as im:
        rgb = np.asarray(im.convert("RGB"), dtype=int)
    assert rgb.shape[:2] == (10000, 1280)
    non_white = float(np.mean(rgb.sum(axis=2) < 720))
    colourful = float(np.mean(rgb.max(axis=2) - rgb.min(axis=2) > 60))
    assert non_white > 0.08, non_white
    assert colourful > 0.02, colourful  # coloured plot lines, colour maps and the robot drawing


@needs_chromium
def test_pdf_export(slew_results, tmp_path):
    html = tmp_path / "r.html"
    r = run_cli("report", slew_results, "-o", html, "--pdf")
    assert r.exit_code == 0, r.output
    pdf = html.with_suffix(".pdf")
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 100_000


@pytest.mark.slow
@needs_chromium
def test_flagship_report_renders_in_chromium(tmp_path):
    out = tmp_path / "pulsar_simple"
    r = run_cli("run", MISSIONS / "pulsar_simple.yaml", "-o", out, "--no-progress")
    assert r.exit_code == 0, r.output
    probe, shot = browser_check(out / "report.html", tmp_path)
    assert probe["errors"] == [] and probe["console"] == [], probe
    assert probe["images"] >= 10 and probe["broken"] == 0, probe
    _assert_shows_plots(shot)
    html = (out / "report.html").read_text()
    for title in ("Mission and model", "ΔV and propellant budget", "Workspace and kinematic indices", "Coupled modes",
                  "Observer gain L", "Synthesis figures"):
        assert title in html
    from test_report_legibility import numeric_columns_without_unit

    assert numeric_columns_without_unit(html) == []  # the LMI tables too (observer gain, γ, verification)


def test_report_lists_the_theses_the_mission_cites_with_titles(slew_results):
    """The slew mission cites Caldera 2019 (in its description): the report's references name it with
    its title, and no thesis the mission does not cite."""
    from sms_cli.references import THESES

    html = (slew_results / "report.html").read_text(encoding="utf-8")
    refs = html[html.index('<section id="references">'):]
    assert "<strong>Caldera 2019</strong>: " + THESES["Caldera 2019"] in refs
    assert "Vicariotto 2023" not in refs and "Kraiem 2022" not in refs
    assert not re.search(r"[Ss]eed 00\d", html)
