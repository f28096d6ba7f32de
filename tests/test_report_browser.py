"""report.html in a real browser: Debian's chromium, headless, driven by
selenium through Debian's chromedriver (no driver is fetched). The page opens
with no console error, every chart draws, the numbers in its tables are the
records', text from a results file stays inert (a CPU model holding an
<img onerror> and a </script>), and the checkbox hides the reference machines
in the table and the chart. It skips where there is no chromium, except under
RAYBENCH_REQUIRE_BROWSER=1 (CI installs it), where that is a failure.
RAYBENCH_SCREENSHOT=PATH also saves the page as the README shows it.

The page is opened from disk with the network off: it must need nothing else.
"""

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from test_report import machine, rec, write

from raybench.bench import report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")
HOSTILE = '<img src=x onerror="window.__pwned=1"></script><script>window.__pwned=2</script>'

ROOT = Path(__file__).resolve().parent.parent


def _browser(tmp_path):
    if not (CHROMIUM and DRIVER):
        if os.environ.get("RAYBENCH_REQUIRE_BROWSER") == "1":
            pytest.fail("RAYBENCH_REQUIRE_BROWSER=1, but no chromium and chromedriver (apt-get install them)")
        pytest.skip("no chromium and chromedriver (apt-get install chromium chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (
        "--headless=new",
        "--no-sandbox",  # CI runs as root
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-default-apps",
        "--disable-extensions",
        "--disable-sync",
        "--no-first-run",
        "--no-default-browser-check",
        "--metrics-recording-only",
        "--window-size=1200,2400",
        f"--user-data-dir={tmp_path / 'profile'}",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    service = webdriver.ChromeService(executable_path=DRIVER, log_output=subprocess.DEVNULL)
    driver = webdriver.Chrome(options=options, service=service)
    driver.set_page_load_timeout(30)
    driver.set_script_timeout(10)
    driver.implicitly_wait(0)
    # no network at all: a page that needed one would fail its checks
    driver.set_network_conditions(offline=True, latency=0, download_throughput=0, upload_throughput=0)
    return driver


def test_report_html_is_one_offline_file_with_the_text_inert(tmp_path, rng):
    """Without a browser: nothing is fetched (no src or href outside the page), and the
    hostile text is escaped in the HTML and in the charts' JSON alike."""
    hostile = machine()
    hostile["cpu"]["model"] = HOSTILE
    records = [rec("thesis", d, n, float(rng.uniform(1, 9)), mach=hostile) for d in ("cpu", "cuda") for n in (100, 500)]
    report.write_report([write(tmp_path / "run.jsonl", records)], tmp_path / "rep")
    page = (tmp_path / "rep" / "report.html").read_text()
    assert not re.search(r"<(script|link|img|iframe)[^>]*(src|href)=", page)
    assert "<img" not in page and page.count("</script>") == page.count("<script")
    assert "&lt;img src=x onerror=&#34;window.__pwned=1&#34;&gt;" in page  # shown in the tables, as text


@pytest.mark.slow  # a browser's start: 3-10 s on 2 cores
def test_report_html_in_a_browser(tmp_path, rng):
    hostile = machine()
    hostile["cpu"]["model"] = HOSTILE
    records = []
    for size, test in (((800, 600), 4), ((1280, 800), 5)):
        for n in (100, 500, 1000):
            cpu = rec("thesis", "cpu", n, float(rng.uniform(20, 60)) * n / 100, size=size, test=test, mach=hostile,
                      options={"accel": "none", "kernel": "fast"})  # fmt: skip
            gpu = rec("thesis", "cuda", n, float(rng.uniform(0.1, 1)) * n / 100, size=size, test=test - 3,
                      mach=hostile, options={"accel": "none", "kernel": "fast"})  # fmt: skip
            records += [cpu, gpu]
    path = write(tmp_path / "run.jsonl", records)
    report.write_report([path], tmp_path / "rep")
    page = tmp_path / "rep" / "report.html"
    driver = _browser(tmp_path)
    try:
        driver.get(page.as_uri())
        ready = "return document.querySelectorAll('div.chart .main-svg').length"
        for _ in range(100):  # plotly draws on load; at most 10 s
            if driver.execute_script(ready) >= 3:
                break
            driver.execute_script("return new Promise(r => setTimeout(r, 100))")
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
        # every chart drew each of its traces
        drawn = driver.execute_script(
            "return Array.from(document.querySelectorAll('div.chart')).map(d => "
            "[d.id, (d.data || []).length, d.querySelectorAll('.main-svg').length, !!d._fullLayout])"
        )
        assert [d[0] for d in drawn] == ["chart-thesis", "chart-speedup", "chart-headline"]
        assert drawn[0][1] == 4 and drawn[1][1] == 2 and drawn[2][1] >= 3, drawn
        assert all(d[2] >= 1 and d[3] for d in drawn), drawn
        # the points table holds the records' numbers
        rows = driver.execute_script(
            "return Array.from(document.querySelectorAll('#points tr')).slice(1).map(r => "
            "Array.from(r.cells).map(c => c.textContent))"
        )
        expected = sorted(
            (r["device"], f"{r['width']}x{r['height']}", str(r["spheres"]), r["frame_ms"]["median"]) for r in records
        )
        got = sorted((d, s, n, float(ms)) for _, d, s, n, ms in rows)
        assert len(got) == len(expected)
        for a, b in zip(got, expected):
            assert a[:3] == b[:3] and a[3] == pytest.approx(b[3], rel=1e-3)
        # the hostile CPU model is shown as written, and ran nothing
        assert HOSTILE in driver.execute_script("return document.getElementById('machines').textContent")
        assert driver.execute_script("return window.__pwned === undefined && document.images.length === 0")
        # the reference machines: in the table and the chart, hidden by the checkbox
        refs = (
            "return Array.from(document.querySelectorAll('#headline tr.reference')).filter(r => r.offsetParent).length"
        )
        assert driver.execute_script(refs) >= 2
        hidden = (
            "var d = document.getElementById('chart-headline');"
            "return d.data.filter(t => t.meta === 'reference' && t.visible !== false).length"
        )
        assert driver.execute_script(hidden) >= 1
        driver.find_element("id", "show-references").click()
        assert driver.execute_script(refs) == 0 and driver.execute_script(hidden) == 0
        assert not [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        if os.environ.get("RAYBENCH_SCREENSHOT"):  # the README's picture: a real run beside the references
            real = ROOT / "benchmarks" / "results" / "xeon-2c" / "headline" / "quick-thesis-20261201.jsonl"
            report.write_report([real], tmp_path / "real")
            driver.get((tmp_path / "real" / "report.html").as_uri())
            driver.execute_script("return new Promise(r => setTimeout(r, 2000))")
            element = driver.find_element("id", "chart-headline")
            driver.execute_script("arguments[0].scrollIntoView()", element)
            element.screenshot(os.environ["RAYBENCH_SCREENSHOT"])
    finally:
        driver.quit()
