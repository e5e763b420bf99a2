"""The dashboard in a real browser: Debian's chromium (``$RVDIAG_TEST_CHROMIUM``, else /usr/bin/chromium) driven by
Playwright against a real uvicorn server process on 127.0.0.1: the numbers on the pages are the API's, the plots
draw, acknowledge works from the page, and no request leaves the server.  Screenshots are kept in the test's tmp
folder.  Without chromium the test skips, except in CI (``CI=true``), where it fails."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from fleet_load import free_port, make_fleet, record_bytes, start_server, stop  # noqa: E402

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
        "--disable-sync", "--no-first-run"]
J1, J2 = "plant/r1/j1", "plant/r1/j2"


def chromium() -> str:
    path = os.environ.get("RVDIAG_TEST_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
    if Path(path).is_file():
        return path
    if os.environ.get("CI") == "true":
        pytest.fail(f"no chromium at {path}: CI must install it (tests/services/start.sh)")
    pytest.skip("no chromium (apt-get install chromium, or set RVDIAG_TEST_CHROMIUM)")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    exe = chromium()
    if os.environ.get("CI") == "true":
        from playwright.sync_api import sync_playwright  # in CI a missing Playwright fails the test
    else:
        sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
    tmp = tmp_path_factory.mktemp("fleet-browser")
    url = f"sqlite:///{tmp / 'fleet.db'}"
    fleet = make_fleet(url, tmp, [J1, J2], seed=3)
    token = fleet.create_token("browser", read_only=False)
    rng = np.random.default_rng(11)
    from datetime import datetime, timedelta, timezone

    from rvdiag.fleet import Reading

    t0 = datetime(2024, 3, 1, tzinfo=timezone.utc)
    for i in range(12):  # J2 healthy; J1 healthy, then loud from the 9th record (alarm)
        for joint, scale in ((J2, 1.0), (J1, 1.0 if i < 8 else 2.5 + 0.1 * i)):
            fleet.ingest(joint, record_bytes(rng, scale, n=2000), filename=f"r{i}.npz", reading=Reading(),
                         time=t0 + timedelta(hours=6 * i))
    fleet.close()
    port = free_port()
    proc = start_server(url, port, tiny=True, log=tmp / "server.log")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=ARGS)
        try:
            yield {"base": f"http://127.0.0.1:{port}", "token": token, "browser": browser, "tmp": tmp, "url": url}
        finally:
            browser.close()
            stop(proc)


@pytest.fixture
def page(server):
    ctx = server["browser"].new_context(viewport={"width": 1280, "height": 900})
    pg = ctx.new_page()
    pg.requests, pg.errors = [], []
    pg.on("request", lambda r: pg.requests.append(r.url))
    pg.on("pageerror", lambda e: pg.errors.append(str(e)))
    pg.on("console", lambda m: pg.errors.append(m.text) if m.type == "error" else None)
    yield pg
    ctx.close()
    outside = [u for u in pg.requests if not u.startswith(server["base"] + "/") and not u.startswith("data:")]
    assert not outside, outside
    assert not pg.errors, pg.errors


def api(server, path):
    import httpx

    return httpx.get(server["base"] + path, timeout=10).json()


def test_fleet_page_shows_the_api_numbers(server, page):
    page.goto(server["base"] + "/")
    rows = api(server, "/api/joints")
    assert page.locator("tr.joint-row").count() == len(rows) == 2
    for row in rows:
        tr = page.locator(f'tr.joint-row[data-joint="{row["joint"]}"]')
        assert tr.locator("td .state").inner_text() == row["state"]
        assert tr.locator("td.last-index").inner_text() == f"{row['last_index']:.4g}"
        assert float(tr.locator("td.last-index").get_attribute("data-value")) == row["last_index"]
        assert tr.locator("td.n-records").inner_text() == str(row["n_records"])
        assert tr.locator("svg.spark polyline").count() == 1
    assert {r["joint"]: r["state"] for r in rows}[J1] == "alarm"
    page.screenshot(path=str(server["tmp"] / "fleet.png"), full_page=True)


def test_joint_page_plots_the_history_of_the_api(server, page):
    page.goto(server["base"] + f"/joints/{J1}")
    page.wait_for_selector("#index-plot[data-drawn=yes]", timeout=30000)
    page.wait_for_selector("#evidence-plot[data-drawn=yes]", timeout=30000)
    hist = [h for h in api(server, f"/api/joints/{J1}/history") if h["health_index"] is not None]
    ys = page.evaluate("""() => document.getElementById('index-plot').data
        .filter(t => t.mode === 'markers').flatMap(t => t.y)""")
    assert sorted(ys) == pytest.approx(sorted(h["health_index"] for h in hist))
    row = api(server, f"/api/joints/{J1}/status")
    assert page.locator("dd.last-index").inner_text() == f"{row['last_index']:.4g}"
    assert page.locator("#joint-state").inner_text() == row["state"]
    assert page.locator("#records-table tbody tr").count() == len(api(server, f"/api/joints/{J1}/history"))
    assert page.evaluate("() => document.getElementById('evidence-plot').data.length") == 3
    page.screenshot(path=str(server["tmp"] / "joint.png"), full_page=True)


def test_acknowledge_from_the_alarms_page(server, page):
    page.goto(server["base"] + "/alarms")
    form = page.locator(f'tr.alarm-row[data-joint="{J1}"] form.write')
    form.locator("input.note").fill("checked on site")
    form.locator("button").click()  # no token yet: refused in the page, nothing sent
    assert "token" in form.locator(".result").inner_text()
    assert api(server, f"/api/joints/{J1}/status")["open_alarm"] is True
    page.fill("#token-input", server["token"])
    page.click("#token-save")
    assert page.evaluate("() => sessionStorage.getItem('rvdiag-token')") == server["token"]
    page.screenshot(path=str(server["tmp"] / "alarms.png"), full_page=True)
    with page.expect_navigation():
        form.locator("button").click()
    page.wait_for_selector("#no-open")
    assert api(server, f"/api/joints/{J1}/status")["open_alarm"] is False
    ev = api(server, f"/api/joints/{J1}/events?kind=acknowledged")[-1]
    assert (ev["by"], ev["note"]) == ("browser", "checked on site")
    assert page.locator("#log-table tr.event-acknowledged").count() == 1
    # the token stays for the tab: the next page still has it
    page.goto(server["base"] + "/")
    assert "kept" in page.locator("#token-state").inner_text()


def test_the_snapshot_opens_from_files_with_no_server(server):
    from fleet_load import TinyJudge

    from rvdiag.fleet import Fleet
    from rvdiag.fleet.web import snapshot

    fleet = Fleet.open(server["url"], judge=TinyJudge())
    try:
        index = snapshot(fleet, server["tmp"] / "snapshot")
    finally:
        fleet.close()
    ctx = server["browser"].new_context(viewport={"width": 1280, "height": 900})
    pg = ctx.new_page()
    urls, errors = [], []
    pg.on("request", lambda r: urls.append(r.url))
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(index.as_uri())
    pg.click(f'a.joint-link:text("{J1}")')
    pg.wait_for_selector("#index-plot[data-drawn=yes]", timeout=30000)
    assert pg.url.endswith(f"/joints/{J1}.html")
    assert not pg.locator("form.write").count()  # nothing to write in a snapshot
    ctx.close()
    assert all(u.startswith("file://") or u.startswith("data:") for u in urls), urls
    assert not errors, errors
