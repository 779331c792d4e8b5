"""Every HTML report as a browser shows it (headless Chromium, when installed): the page is no
wider than the window, and every image loads."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from delaytrack.cli import main
from delaytrack.experiments import robustness

BROWSER = next(
    (
        shutil.which(name)
        for name in ("chromium", "chromium-browser", "google-chrome")
        if shutil.which(name)
    ),
    None,
)
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(BROWSER is None, reason="no headless Chromium installed"),
]
EXAMPLES = Path(__file__).parents[1] / "examples"
WIDTH = 1400

# Written into the page after it loads; the browser's DOM dump then carries the answer.
_PROBE = """<script>window.addEventListener('load', () => {
  const images = Array.from(document.images);
  const wide = Array.from(document.body.querySelectorAll('*')).filter(e => {
    const r = e.getBoundingClientRect();
    return r.right > window.innerWidth + 1 && !e.closest('.wide');
  }).map(e => e.tagName + ': ' + (e.textContent || '').slice(0, 60));
  document.body.setAttribute('data-probe', JSON.stringify({
    page: document.documentElement.scrollWidth, window: window.innerWidth,
    images: images.length, broken: images.filter(i => !(i.complete && i.naturalWidth > 0)).length,
    wide: wide}));
});</script>"""


def rendered(report: Path, tmp_path: Path) -> dict:
    """The probe's findings for ``report`` rendered at :data:`WIDTH` px."""
    page = tmp_path / f"probe-{report.parent.name}.html"
    page.write_text(report.read_text().replace("</body>", _PROBE + "</body>"))
    dom = subprocess.run(
        [
            BROWSER,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--window-size={WIDTH},1000",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    start = dom.index("data-probe=") + len("data-probe=") + 1
    quote = dom[start - 1]
    text = dom[start : dom.index(quote, start)].replace("&quot;", '"').replace("&amp;", "&")
    return json.loads(text)


@pytest.fixture(scope="module")
def reports(tmp_path_factory, monkeypatch_module):
    out = tmp_path_factory.mktemp("reports")
    monkeypatch_module.setitem(robustness.SIZES, "default", robustness.StudySize(1, 1, 2))
    quiet = ["--quiet"]
    assert main(["reproduce", "--out", str(out), "--duration", "1", "--no-contact", *quiet]) == 0
    assert (
        main(["reproduce", "--job", "two-link", "--out", str(out), "--duration", "1", *quiet]) == 0
    )
    assert (
        main(["reproduce", "--job", "margins", "--out", str(out), "--duration", "6", *quiet]) == 0
    )
    sweep = out / "sweep"
    assert main(["sweep", str(EXAMPLES / "sweep_small.toml"), "--out", str(sweep), *quiet]) == 0
    return {
        "paper": out / "paper" / "report.html",
        "paper-literal": out / "paper-literal" / "report.html",
        "robustness": out / "robustness" / "report.html",
        "two-link": out / "two-link" / "report.html",
        "margins": out / "margins" / "report.html",
        "sweep": sweep / "report.html",
    }


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


@pytest.mark.parametrize(
    "name", ["paper", "paper-literal", "robustness", "two-link", "margins", "sweep"]
)
def test_report_fits_the_window_and_every_image_loads(reports, name, tmp_path):
    probe = rendered(reports[name], tmp_path)
    assert probe["images"] > 0 and probe["broken"] == 0, probe
    assert probe["page"] <= probe["window"], probe
    assert probe["wide"] == [], probe
