"""The report reads at its displayed size, in a real browser and on paper (issue #15, items 2 and 3).

Measured in headless Chromium at a 1280 px window: every figure is shown at ≥ 90 % of its natural
width, or can be enlarged and its own text is legible; the text the plotting code drew (smallest
font, from the PNG's ``sms:font-px-min`` chunk) is ≥ 10 px on screen, and no two text boxes of a
figure collide; click-to-enlarge fills the window; the verdicts come before the first figure and
their status colour sits on the status cell; every numeric column says its unit; no number is broken
across lines. The PDF: A4 pages, "page k of N" on each, no text beyond the page, the print layout
fits tables in the A4 width without a scroll box, and page 1 (rendered to PNG) is the title page.

Chromium and poppler come from Debian (``scripts/test.sh`` installs both when it can); the tests say
which is missing when they skip.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

from conftest import run_cli
from test_report_render import CHROMIUM, chromium, needs_chromium, shared_slew_results

needs_poppler = pytest.mark.skipif(shutil.which("pdftoppm") is None or shutil.which("pdftotext") is None,
                                   reason="poppler is not installed (Debian: apt-get install -y poppler-utils)")
MIN_FONT_PX = 10.0
A4_PT = (595.28, 841.89)
A4_CONTENT_PX = 703  # 210 mm − 2 × 12 mm margins at 96 CSS px per inch
PASS_RGB = "rgb(30, 123, 52)"

PROBE = r"""<script>
window.addEventListener('load', function () {
  function top(e) { return e.getBoundingClientRect().top + window.scrollY; }
  var imgs = Array.prototype.map.call(document.images, function (i) {
    var fig = i.closest('figure'), zoom = i.closest('a.zoom'), r = i.getBoundingClientRect();
    return {id: fig ? fig.id : '', nw: i.naturalWidth, cw: i.clientWidth, font: parseFloat(i.dataset.fontPx || '0'),
            enlargeable: !!(fig && zoom && zoom.getAttribute('href') === '#' + fig.id && fig.querySelector('a.close')),
            top: top(i), rw: r.width, position: getComputedStyle(i).position};
  });
  var req = document.querySelector('#requirements table');
  var status = Array.prototype.map.call(document.querySelectorAll('#requirements tbody tr'), function (tr) {
    var cells = tr.querySelectorAll('td');
    return {status: getComputedStyle(tr.querySelector('td.status')).color,
            other: getComputedStyle(cells[0]).color, text: tr.querySelector('td.status').textContent};
  });
  function lines(range) {  // the line boxes a range of text occupies
    var tops = {}; Array.prototype.forEach.call(range.getClientRects(), function (c) { if (c.width > 0) tops[Math.round(c.bottom)] = 1; });
    return Object.keys(tops).length;
  }
  var broken = [], walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT), node;
  var number = /[-+\u2212]?\d[\d\u202f]*(\.\d+)?([eE][-+]?\d+)?/g;
  while ((node = walker.nextNode())) {  // every number of the text as shown, however it is marked up
    if (node.parentElement.closest('script, style, pre, .hash')) continue;  // hashes break anywhere: not numbers
    var m; number.lastIndex = 0;
    while ((m = number.exec(node.data))) {
      if (m[0].length < 3) continue;
      var r = document.createRange(); r.setStart(node, m.index); r.setEnd(node, m.index + m[0].length);
      if (lines(r) > 1) broken.push(m[0]);
    }
  }
  Array.prototype.forEach.call(document.querySelectorAll('span.n, td.num'), function (e) {  // and each number with its unit
    var r = document.createRange(); r.selectNodeContents(e); if (lines(r) > 1) broken.push(e.textContent); });
  var scrolling = Array.prototype.filter.call(document.querySelectorAll('.wrap'), function (w) {
    return w.scrollWidth > w.clientWidth + 1; }).map(function (w) { return w.querySelector('caption, th').textContent; });
  var p = document.createElement('pre'); p.id = '__probe';
  p.textContent = JSON.stringify({images: imgs, requirements_top: req ? top(req) : null, status: status, broken: broken,
    scrolling: scrolling, body_width: document.body.scrollWidth, hash: location.hash,
    title_break: getComputedStyle(document.querySelector('.titlepage')).breakAfter});
  document.body.appendChild(p);
});
</script>"""


def probe(report: Path, tmp_path: Path, width: int = 1280, fragment: str = "", print_layout: bool = False) -> dict:
    """Load a copy of the report with the probe (optionally with its print rules applied on screen)."""
    html = report.read_text(encoding="utf-8")
    if print_layout:
        html = html.replace("@media print {", "@media all {", 1)
    page = tmp_path / f"probe-{width}-{int(print_layout)}.html"
    page.write_text(html.replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    r = chromium("--hide-scrollbars", f"--window-size={width},1000", "--virtual-time-budget=10000", "--dump-dom",
                 page.as_uri() + fragment)
    m = re.search(r'<pre id="__probe">(.*?)</pre>', r.stdout, re.S)
    assert m, f"probe did not run: {r.stderr[-2000:]}"
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))


def png_chunks(html: str) -> dict[str, dict]:
    """Figure id → the text chunks of its embedded PNG."""
    from sms_cli.report.figstyle import png_info

    out = {}
    for fid, b64 in re.findall(r'<figure id="([^"]+)"[^>]*>.*?src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html, re.S):
        out[fid] = png_info(base64.b64decode(b64))["text"]
    return out


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    return shared_slew_results(tmp_path_factory)


# ----------------------------------------------------------------- figures


@needs_chromium
def test_every_figure_is_legible_at_its_displayed_size(results, tmp_path):
    p = probe(results / "report.html", tmp_path)
    chunks = png_chunks((results / "report.html").read_text(encoding="utf-8"))
    assert len(p["images"]) >= 16
    for img in p["images"]:
        ratio = img["cw"] / img["nw"]
        assert ratio >= 0.9 or (img["enlargeable"] and img["font"] >= MIN_FONT_PX), img
        meta = chunks[img["id"]]
        # every figure of this run is drawn by sms: its smallest text, scaled as shown, is ≥ 10 px,
        # no two of its text boxes are closer than 2 px and none leaves the image
        assert float(meta["sms:font-px-min"]) * ratio >= MIN_FONT_PX, (img, meta)
        assert meta["sms:text-overlaps"] == "0" and meta["sms:text-clipped"] == "0", (img, meta)
        assert img["enlargeable"], img


@needs_chromium
def test_a_click_enlarges_a_figure_to_the_window(results, tmp_path):
    normal = {i["id"]: i for i in probe(results / "report.html", tmp_path)["images"]}
    half = next(i for i in normal.values() if i["nw"] < 600)  # the robot drawing: half the column
    big = probe(results / "report.html", tmp_path, fragment="#" + half["id"])
    shown = next(i for i in big["images"] if i["id"] == half["id"])
    assert big["hash"] == "#" + half["id"] and shown["position"] == "fixed"
    assert shown["rw"] >= 0.9 * 1280 and shown["rw"] >= 2 * half["cw"], (half, shown)


@needs_chromium
def test_verdicts_come_first_with_the_colour_on_the_status_cell(results, tmp_path):
    p = probe(results / "report.html", tmp_path)
    assert p["requirements_top"] is not None
    assert p["requirements_top"] < min(i["top"] for i in p["images"])
    assert p["status"] and all(s["text"] == "PASS" and s["status"] == PASS_RGB and s["other"] != PASS_RGB
                               for s in p["status"]), p["status"]


@needs_chromium
def test_no_number_is_broken_across_lines(results, tmp_path):
    for width in (1280, 400):  # a narrow window wraps every long cell
        p = probe(results / "report.html", tmp_path, width=width)
        assert p["broken"] == [], (width, p["broken"][:10])


# ----------------------------------------------------------------- units


class _Tables(HTMLParser):
    """Each table as (caption, headers, rows of (text, is_numeric))."""

    def __init__(self):
        super().__init__()
        self.tables: list[dict] = []
        self.cell: list[str] | None = None
        self.num = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self.tables.append({"caption": "", "headers": [], "rows": []})
        elif tag in ("th", "td", "caption") and self.tables:
            self.cell, self.num = [], "num" in (a.get("class") or "").split()
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])

    def handle_data(self, data):
        if self.cell is not None:
            self.cell.append(data)

    def handle_endtag(self, tag):
        if tag in ("th", "td", "caption") and self.cell is not None and self.tables:
            text, t = "".join(self.cell).strip(), self.tables[-1]
            if tag == "caption":
                t["caption"] = text
            elif tag == "th":
                t["headers"].append(text)
            else:
                t["rows"][-1].append((text, self.num))
            self.cell = None


BARE_NUMBER = re.compile(r"[-+−]?(\d[\d\u202f]*(\.\d*)?|\.\d+)([eE][-+]?\d+)?")  # a number without its unit
NO_UNIT = {"#", "mode"}  # counts and indices


def numeric_columns_without_unit(html: str) -> list[str]:
    """Columns holding bare numbers whose header has no [unit], in tables without a unit column."""
    parser = _Tables()
    parser.feed(html)
    missing = []
    for t in parser.tables:
        h = t["headers"]
        if "unit" in h:
            continue
        for k, head in enumerate(h):
            bare = [r[k][0] for r in t["rows"] if k < len(r) and BARE_NUMBER.fullmatch(r[k][0])]
            if bare and not re.search(r"\[.+\]", head) and head not in NO_UNIT:
                missing.append(f"{t['caption'] or h}: {head}")
    return missing


def test_every_numeric_column_says_its_unit(results):
    html = (results / "report.html").read_text(encoding="utf-8")
    assert numeric_columns_without_unit(html) == []
    for unit in ("N\u00a0m\u00a0s", "kg\u00a0m²", "rad/s", "[rpm]", "N m s", "[1/s]", "[rad/s²]", "[s/rad]"):
        assert unit in html, unit


def test_synthesis_and_conservation_tables_name_each_quantity_and_unit(tmp_path):
    """The tables issue #15 found with raw keys: synthesis figures, conservation checks, observer gain."""
    import yaml

    from sms_cli.report.sections import simulation_section, synthesis_section

    (tmp_path / "gains.yaml").write_text(yaml.safe_dump({
        "law": "lmi", "observer": {"states": ["left_panel_mode1", "w0_x", "left_panel_mode1_rate"], "outputs": ["w0_x"],
                                   "L": [[1.0], [2.0], [3.0]]},
        "verification": {"passed": True, "checks": [{"name": "gamma_bound", "passed": True, "detail": "d", "value": 0.07,
                                                       "limit": 0.7}]}}))
    sy = {"law": "lmi", "gamma": 0.85, "worst_cost": {"gramian": 0.07}, "lmi": {"solve_time_s": 3.0, "n_variables": 410},
          "regions": {"controller": {"decay_rate": 0.05, "min_damping": 0.7, "max_frequency": 0.5}},
          "gains": [{"actuator": "rw1", "kp_1_s2": 0.25, "kv_1_s": 0.7, "damping": 0.7}]}
    s = synthesis_section(sy, tmp_path)
    tables = {t.caption.split(" (")[0]: t for t in s.tables}
    figures = tables["Synthesis figures"]
    assert figures.headers == ["quantity", "value", "unit"]
    assert {r[0]: r[2] for r in figures.rows} == {  # labelled, not raw dotted keys, each with its unit
        "γ: guaranteed bound on √∫ε_cᵀε_c (solver)": "√s × ε_c unit",
        "worst ∫ε_cᵀε_c over the initial errors (Gramian)": "s × ε_c unit²", "solve time": "s",
        "decision variables": "count"}
    observer = tables["Observer gain L"]
    assert [r[1] for r in observer.rows] == ["√kg m/rad", "1/s", "√kg m/(rad s)"]
    assert tables["Gains per actuator"].headers == ["actuator", "kp [1/s²]", "kv [1/s]", "damping ratio ζ [–]"]
    check = tables["Verification of the gains"]
    assert check.headers[:5] == ["check", "status", "value", "limit", "unit"] and check.status_col == 1
    assert check.rows[0][4] == "s × ε_c unit²"
    sim = simulation_section({"conservation": {"angular_momentum_drift_abs": 1e-11, "energy_change_J": 67.6}}, tmp_path,
                             [], [])
    assert [(r[0], r[2]) for r in sim.tables[0].rows] == [("angular momentum drift, absolute", "N m s"),
                                                          ("mechanical energy change (work of the actuators)", "J")]


# ----------------------------------------------------------------- PDF


def _pages(pdf: Path) -> list[tuple[float, float]]:
    """(width, height) in pt of every page, from the PDF's page objects."""
    data = pdf.read_bytes()
    boxes = re.findall(rb"/Type\s*/Page\b(?!s).*?/MediaBox\s*\[\s*([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s*\]", data, re.S)
    return [(float(x1) - float(x0), float(y1) - float(y0)) for x0, y0, x1, y1 in boxes]


@pytest.fixture(scope="module")
def pdf(results, tmp_path_factory) -> Path:
    if not CHROMIUM.exists():
        pytest.skip("chromium is not installed (Debian: apt-get update && apt-get install -y chromium)")
    html = tmp_path_factory.mktemp("pdf") / "report.html"
    r = run_cli("report", results, "-o", html, "--pdf")
    assert r.exit_code == 0, r.output
    return html.with_suffix(".pdf")


@needs_chromium
def test_pdf_is_a4_with_every_page_within_it(pdf):
    pages = _pages(pdf)
    assert len(pages) >= 5, pages
    for w, h in pages:
        assert abs(w - A4_PT[0]) < 1.5 and abs(h - A4_PT[1]) < 1.5, (w, h)


@needs_chromium
@needs_poppler
def test_pdf_numbers_its_pages_and_keeps_text_inside_them(pdf):
    n = len(_pages(pdf))
    box = subprocess.run(["pdftotext", "-bbox", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    pages = re.findall(r'<page width="([\d.]+)" height="([\d.]+)">(.*?)</page>', box, re.S)
    assert len(pages) == n
    margin = 12 / 25.4 * 72 - 2  # the @page side margins, less 2 pt
    for k, (w, _, body) in enumerate(pages, 1):
        words = re.findall(r'<word xMin="([\d.]+)" yMin="[\d.]+" xMax="([\d.]+)" yMax="[\d.]+">(.*?)</word>', body)
        text = " ".join(wd for *_, wd in words)
        assert f"page {k} of {n}" in text, (k, text[-200:])
        outside = [wd for x0, x1, wd in words if float(x0) < margin or float(x1) > float(w) - margin]
        assert outside == [], (k, outside[:10])



@needs_chromium
def test_print_layout_fits_tables_in_the_a4_width(results, tmp_path):
    """The print rules applied on screen at the A4 text width: no table needs a scroll box (Chromium
    would print it cut, with its scrollbar) and nothing is wider than the page (it would shrink the page)."""
    p = probe(results / "report.html", tmp_path, width=A4_CONTENT_PX, print_layout=True)
    assert p["scrolling"] == [] and p["body_width"] <= A4_CONTENT_PX + 1, p["scrolling"]
    assert p["title_break"] == "page"  # the verdicts have page 1 to themselves
    assert all(i["cw"] <= A4_CONTENT_PX for i in p["images"])


@needs_chromium
@needs_poppler
def test_pdf_page_one_is_the_title_page_with_the_verdict(pdf, results, tmp_path):
    import numpy as np
    from PIL import Image

    def page(k: int) -> str:
        return subprocess.run(["pdftotext", "-f", str(k), "-l", str(k), "-layout", str(pdf), "-"], capture_output=True,
                              text=True, check=True).stdout

    text = page(1)
    name = json.loads((results / "results.json").read_text())["run"]["mission"]
    assert name in text and "requirements met" in text and "Requirement verdicts" in text and "Stages" in text
    assert page(2).split()[:3] == ["Mission", "and", "model"]  # the sections start on page 2
    subprocess.run(["pdftoppm", "-r", "60", "-png", "-f", "1", "-l", "1", str(pdf), str(tmp_path / "page")], check=True)
    with Image.open(next(tmp_path.glob("page*.png"))) as im:
        rgb = np.asarray(im.convert("RGB"), dtype=int)
    h, w, _ = rgb.shape
    assert abs(h / w - A4_PT[1] / A4_PT[0]) < 0.01
    top = rgb[: h // 4]
    green = np.all(np.abs(top - [227, 243, 230]) < 6, axis=2)  # the verdict's pass background
    assert green.mean() > 0.002, green.mean()
    colourful = float(np.mean(rgb.max(axis=2) - rgb.min(axis=2) > 60))
    assert colourful < 0.01, colourful  # text and tables only: no plot on the title page
