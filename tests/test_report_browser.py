"""Issue 19, part 2: the smoothing report as a CAM programmer sees it, rendered by headless
Chromium: no Python repr, no 'nan' in the visible text, no empty figure, sections numbered in
order, a verdict per method first, at most ten summary columns."""

from __future__ import annotations

import base64
import html
import io
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from camsmooth.report.smoothing import HTML_FILE, write_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium not found (chromium on the PATH)")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")
REPRS = ("np.float64", "np.int64", "array(", "Machine(", "PostConfig(", "ToroidalCutter(", "AxisLimits(",
         "ErrorModel(", "<function", "object at 0x")


def chromium(args: list[str], profile: Path, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """Run headless Chromium with a fresh profile folder."""
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args], capture_output=True, text=True,
                          timeout=timeout)


def visible_text(dom: str) -> str:
    """The text a reader sees: the DOM without style, script, tags (image data included)."""
    dom = re.sub(r"(?is)<(style|script)[^>]*>.*?</\1>", " ", dom)
    dom = re.sub(r"(?s)<[^>]*>", " ", dom)
    return html.unescape(re.sub(r"\s+", " ", dom))


def check_report_page(report: Path, tmp_path: Path) -> str:
    """Render ``report`` in Chromium; assert no repr, no NaN, no empty figure; return the text."""
    res = chromium(["--dump-dom", report.resolve().as_uri()], tmp_path / "profile-dom")
    assert res.returncode == 0, res.stderr[-2000:]
    dom = res.stdout
    text = visible_text(dom)
    for bad in REPRS:
        assert bad not in text, f"{bad!r} in the report's visible text"
    assert not re.search(r"(?i)\bnan\b", text), re.search(r"(?i).{60}\bnan\b.{60}", text)
    assert not re.search(r"\b\d+\.\d{9,}\b", text), "a long float in the visible text"
    markup = re.sub(r"(?is)<script[^>]*>.*?</script>", " ", dom)  # plotly.js carries data URIs of its own
    images = re.findall(r"src=\"data:image/png;base64,([^\"]+)\"", markup) + re.findall(
        r"src='data:image/png;base64,([^']+)'", markup)
    assert images, "no figure in the report"
    for b64 in images:
        img = imread(io.BytesIO(base64.b64decode(b64)), format="png")
        rgb = img[..., :3]
        assert np.ptp(rgb) > 0, "an empty figure"
        assert np.mean(rgb.min(axis=-1) < 0.9) > 0.005, "a figure with (almost) nothing drawn"
    shot = tmp_path / "shot.png"
    res = chromium(["--window-size=1400,1800", f"--screenshot={shot}", report.resolve().as_uri()],
                   tmp_path / "profile-shot")
    assert res.returncode == 0 and shot.exists(), res.stderr[-2000:]
    assert np.ptp(imread(shot)[..., :3]) > 0
    return text


@pytest.fixture(scope="module")
def smoothed():
    from tests.test_own_outputs import _smooth

    return _smooth("linuxcnc")


@pytest.fixture(scope="module")
def report_dir(smoothed, tmp_path_factory):
    """The report of ``smoothed``, written once for the tests of this module."""
    return write_report(smoothed, tmp_path_factory.mktemp("report") / "rep")


@needs_chromium
def test_report_reads_as_a_programmer_needs_it(smoothed, report_dir, tmp_path):
    out = report_dir
    text = check_report_page(out / HTML_FILE, tmp_path)
    heads = re.findall(r"<h2>(\d+)\. ([^<]*)</h2>", (out / HTML_FILE).read_text(encoding="utf-8"))
    assert [int(k) for k, _ in heads] == list(range(1, len(heads) + 1))  # numbered in order
    assert heads[0][1] == "Verdict" and heads[1][1] == "Summary" and heads[2][1].startswith("Per row")
    nlp = smoothed.methods["nlp"].metrics
    # the verdict: both cycle times, the binding limit, peaks, violations, worst clearance with its place
    assert f"cycle time {nlp.cycle_time_optimal_s:.4g} s time-optimal, {nlp.cycle_time_s:.4g} s on the linuxcnc" in text
    assert "binds most in the time-optimal law:" in text
    assert "under the planned law" in text and "at the programmed feed" in text
    assert re.search(r"worst clearance -?[\d.e-]+ µm at row \d+, point \d+", text)
    # Setup in mm and degrees: the windows as written by a person
    assert "lead window 2 to 20 deg" in text and "tilt window -15 to 15 deg" in text
    assert "travel -100 to 100 deg, vmax 60 deg/s, amax 300 deg/s²" in text
    # the cutting geometry: R / sin(lead) + r and the scallop at the stepover
    assert "effective radius across the feed" in text and "scallop at stepover" in text
    summary = re.search(r"<table class='summary'>(.*?)</table>", (out / HTML_FILE).read_text(), re.S).group(1)
    assert len(re.findall(r"<th>", summary.split("</tr>")[0])) <= 10


def test_effective_radius_and_scallop_closed_form():
    """docs/METHODS.md section 1.3: R = 4, r = 1 mm, lead 10 deg: r_eff = 4 / sin 10 deg + 1 = 24.0
    mm; s = 1 mm: h = 5.2 um."""
    from types import SimpleNamespace

    from camsmooth.report.smoothing import effective_radius, scallop_um, stepover_mm

    r_eff = effective_radius(SimpleNamespace(R=4.0, r=1.0), np.radians([10.0]), np.zeros(1))
    np.testing.assert_allclose(r_eff, 4.0 / np.sin(np.radians(10.0)) + 1.0, rtol=1e-12)
    np.testing.assert_allclose(scallop_um(r_eff, 1.0), 1e3 * (r_eff - np.sqrt(r_eff ** 2 - 0.25)), rtol=1e-12)
    assert 5.1 < float(scallop_um(r_eff, 1.0)[0]) < 5.3
    # tilt 90 deg: the corner's own radius across the feed
    np.testing.assert_allclose(effective_radius(SimpleNamespace(R=4.0, r=1.0), np.radians([10.0]),
                                                np.radians([90.0])), 1.0, rtol=1e-9)
    rows = np.repeat(np.arange(3), 5)
    cc = np.column_stack([np.tile(np.arange(5.0), 3), 2.5 * rows, np.zeros(15)])
    assert stepover_mm(cc, rows) == pytest.approx(2.5)


# The interactive 3D view (camsmooth.report.view3d) in the real page: a hook placed before every
# other script reports script errors (uncaught, rejected promises, console.error) and, once the
# page has run, the WebGL canvases of the view on the console, which Chromium logs to stderr.
_HOOK = """<script>
(function () {
  var say = function (m) { console.log('CAMSMOOTH-ERROR ' + m); };
  window.addEventListener('error', function (e) { say(e.message); });
  window.addEventListener('unhandledrejection', function (e) { say('rejected: ' + e.reason); });
  var ce = console.error;
  console.error = function () { say(Array.prototype.join.call(arguments, ' ')); ce.apply(console, arguments); };
  window.addEventListener('load', function () { setTimeout(function () {
    var c = document.querySelectorAll('#camsmooth-view3d canvas');
    console.log('CAMSMOOTH-CANVAS ' + Array.prototype.map.call(c, function (x) {
      var r = x.getBoundingClientRect(); return Math.round(r.width) + 'x' + Math.round(r.height); }).join(' '));
  }, 1500); });
})();
</script>"""
# the view alone at the top of the window (plotly's text-measuring svg, a child of body, stays)
_VIEW_ONLY = "<style>body > :not(figure.view3d):not(svg) { display: none !important; }</style>"


def _near(rgb: np.ndarray, colour: tuple[int, int, int], tol: float) -> np.ndarray:
    return np.abs(rgb - np.asarray(colour, float)).max(axis=-1) <= tol


@needs_chromium
def test_interactive_view_loads_without_script_error_and_draws(smoothed, report_dir, tmp_path, capsys):
    from camsmooth.cli.main import _print_summary
    from camsmooth.report.view3d import DIV_ID

    page = (report_dir / HTML_FILE).read_text(encoding="utf-8")
    assert DIV_ID in page and "<script src=" not in page and "cdn.plot.ly/plotly" not in page  # no network
    probe = tmp_path / "probe.html"
    probe.write_text(page.replace("<head>", "<head>" + _HOOK, 1).replace("</head>", _VIEW_ONLY + "</head>", 1),
                     encoding="utf-8")
    shot = tmp_path / "view.png"
    res = chromium(["--enable-unsafe-swiftshader", "--enable-logging=stderr", "--v=0", "--window-size=1200,900",
                    "--virtual-time-budget=8000", f"--screenshot={shot}", probe.resolve().as_uri()],
                   tmp_path / "profile-view")
    assert res.returncode == 0 and shot.exists(), res.stderr[-2000:]
    console = [ln for ln in res.stderr.splitlines() if "CONSOLE" in ln]
    errors = [ln for ln in console if "CAMSMOOTH-ERROR" in ln or "Uncaught" in ln]
    assert not errors, errors
    canvases = [ln for ln in console if "CAMSMOOTH-CANVAS" in ln]
    assert canvases, "the hook never ran: " + "\n".join(console[-5:])
    sizes = [tuple(map(int, wh)) for wh in re.findall(r"(\d+)x(\d+)", canvases[0].split("CAMSMOOTH-CANVAS")[1])]
    assert sizes and max(w * h for w, h in sizes) > 600 * 400, sizes  # the WebGL canvas fills the view
    rgb = 255.0 * imread(shot)[..., :3]
    box = rgb[:700]  # the view's 720 px (the caption below)
    # the part: grey shading (r = g = b), neither the page's white nor the scene's blue-grey
    grey = (np.ptp(box, axis=-1) < 10) & (box[..., 0] > 90) & (box[..., 0] < 225)
    assert grey.mean() > 0.05, f"the part covers {100 * grey.mean():.2f}% of the view"
    # the primary method's path and tool axes in its colour (#d62728), more than its legend swatches
    red = _near(box, (214, 39, 40), 45)
    assert red.sum() > 2000, f"{int(red.sum())} pixels in nlp's colour"
    # the headline: the same facts in the report and in the smooth summary, each before -> after from
    # the methods' metrics (the program as brought: 'none', this path has no CAM axes)
    none, nlp = smoothed.methods["none"].metrics, smoothed.result.metrics
    _print_summary(smoothed)
    printed = capsys.readouterr().out
    text = visible_text(page)
    cyc = (f"cycle time on the linuxcnc controller {none.cycle_time_s:.4g} s -> {nlp.cycle_time_s:.4g} s "
           f"({100 * (nlp.cycle_time_s / none.cycle_time_s - 1):+.0f}%)")
    opt = (f"cycle time time-optimal {none.cycle_time_optimal_s:.4g} s -> {nlp.cycle_time_optimal_s:.4g} s "
           f"({100 * (nlp.cycle_time_optimal_s / none.cycle_time_optimal_s - 1):+.0f}%)")
    viol = f"limit violations {sum(none.violations.values())} -> {sum(nlp.violations.values())}"
    clear = f"worst clearance {1e3 * none.min_delta:.3g} \u00b5m -> {1e3 * nlp.min_delta:.3g} \u00b5m"
    for fact in (cyc, opt, viol, clear):
        assert fact in text and fact in printed, fact
    assert text.index(cyc) < text.index("nlp (primary)")  # the headline before the per-method verdict
    assert printed.index(cyc) < printed.index("method ")  # and before the summary's table
