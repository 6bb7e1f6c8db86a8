"""The dashboard and the docs in a real browser (headless chromium) against a real server.

The page must list a stored run, take the service's key, start a run with its button and
draw the run live from the event stream while it runs; /docs and /redoc must render from
the service's own assets (chromium here has no internet, so a CDN would leave them blank).
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from stand.runfile import format_run
from tests.integration import test_api_support
from tests.integration.browser import chromium, needs_chromium
from tests.integration.test_api_support import Server, serve

pytestmark = needs_chromium

#: Wall-time bounds on 2 shared cores, s.
PAGE_TIMEOUT_S = 30.0
RUN_TIMEOUT_S = 120.0
#: Run length of the live run, s of stand time: long enough that the event stream (polled
#: every 0.2 s by the service) delivers several batches while it runs in lockstep.
LIVE_DURATION_S = 5.0
ROOT = Path(__file__).resolve().parents[2]


def wait_for(condition, timeout_s: float = PAGE_TIMEOUT_S, what: str = "condition"):  # type: ignore[no-untyped-def]
    return test_api_support.wait_for(condition, timeout_s, what)


def click_row(driver, table: str, row_id: str) -> None:  # type: ignore[no-untyped-def]
    """Click the row of ``row_id``; the page redraws its tables every 2 s, so a row found a
    moment ago may be gone: find it again until the click lands."""
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.by import By

    def click() -> bool:
        try:
            rows = driver.find_elements(By.CSS_SELECTOR, f'#{table} tbody tr[data-id="{row_id}"]')
            if rows:
                rows[0].click()
            return bool(rows)
        except StaleElementReferenceException:
            return False

    wait_for(click, what=f"row {row_id} of #{table} clicked")


def upload_run(server: Server) -> str:
    t = np.arange(500) * 1e-3
    text = format_run({"time_s": t, "current_A": 0.1 * np.sin(20 * t),
                       "position_rad": np.cos(20 * t)})
    with server.client() as client:
        answer = client.post("/runs/upload", files={"file": ("bench.csv", text, "text/csv")})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    with serve(tmp_path_factory.mktemp("dashboard")) as running:
        yield running


def test_dashboard_lists_runs_and_plots_a_run_live(server: Server, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    stored = upload_run(server)
    with chromium(tmp_path / "profile") as driver:
        driver.get(server.base_url + "/")  # type: ignore[attr-defined]
        find = driver.find_element  # type: ignore[attr-defined]
        wait_for(lambda: find(By.TAG_NAME, "body").get_attribute("data-ready"), what="page ready")
        rows = driver.find_elements(By.CSS_SELECTOR, "#runs tbody tr")  # type: ignore[attr-defined]
        assert stored in [row.get_attribute("data-id") for row in rows]

        # The service has a key: the page asks for it, and starting without it is refused.
        assert find(By.ID, "key-box").is_displayed()
        Select(find(By.ID, "experiment")).select_by_value("seed000_no_load")
        duration = find(By.ID, "duration")
        duration.clear()
        duration.send_keys(str(LIVE_DURATION_S))
        find(By.ID, "start").click()
        wait_for(lambda: "key" in find(By.ID, "control-note").text, what="refusal without key")
        find(By.ID, "key").send_keys(server.api_key)
        find(By.ID, "key-save").click()
        find(By.ID, "start").click()

        # Watch the live canvas: it must be redrawn with more points while the run runs.
        canvas = find(By.ID, "live")
        seen: list[tuple[int, int]] = []  # (updates, samples) while the state was 'running'
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while (state := canvas.get_attribute("data-state")) not in ("done", "failed", "aborted"):
            assert time.monotonic() < deadline, f"run not over in {RUN_TIMEOUT_S} s ({state})"
            if state == "running":
                seen.append((int(canvas.get_attribute("data-updates")),
                             int(canvas.get_attribute("data-samples"))))
            time.sleep(0.05)
        assert state == "done"
        updates = sorted({u for u, _ in seen if u > 0})
        assert len(updates) >= 2, f"live plot redrawn {updates} times during the run"
        samples = [s for u, s in seen if u > 0]
        assert samples[-1] > samples[0], f"the live plot did not grow during the run: {samples}"
        assert int(canvas.get_attribute("data-points")) > 0
        if os.environ.get("STAND_SCREENSHOTS"):  # refresh the README's picture on demand
            click_row(driver, "runs", canvas.get_attribute("data-run"))
            wait_for(lambda: int(find(By.ID, "run-plot").get_attribute("data-points")) > 0)
            driver.save_screenshot(str(tmp_path / "dashboard.png"))  # type: ignore[attr-defined]
            shutil.copy(tmp_path / "dashboard.png", ROOT / "docs" / "dashboard.png")


@pytest.mark.parametrize(("path", "rendered"), [
    ("/docs", ".swagger-ui .opblock"),  # one block per route, drawn by swagger-ui-bundle.js
    ("/redoc", ".api-content h1"),  # the API's title, drawn by redoc.standalone.js
])
def test_docs_render_offline(server: Server, tmp_path: Path, path: str, rendered: str) -> None:
    from selenium.webdriver.common.by import By

    with chromium(tmp_path / "profile") as driver:
        driver.get(server.base_url + path)  # type: ignore[attr-defined]
        found = wait_for(lambda: driver.find_elements(By.CSS_SELECTOR, rendered),  # type: ignore[attr-defined]
                         what=f"{path} rendered")
        assert "motorstand" in driver.page_source  # type: ignore[attr-defined]
        assert len(found) >= 1


def test_a_result_report_opens_with_its_figures_and_limits(server: Server, tmp_path: Path) -> None:
    """A stored run, identified over HTTP; its report in chromium, and in the dashboard."""
    from selenium.webdriver.common.by import By

    with server.client() as client:
        answer = client.post("/runs", json={"profile": "seed000_no_load",
                                            "overrides": {"duration_s": 2.0, "repeats": 1}})
        assert answer.status_code == 202, answer.text
        run_id = answer.json()["runs"][0]
        wait_for(lambda: client.get(f"/runs/{run_id}").json()["state"] == "done",
                 RUN_TIMEOUT_S, "run done")
        result = client.post("/identify", json={"run": run_id})
        assert result.status_code == 200, result.text
        result_id = result.json()["result_id"]
        assert client.get(f"/results/{result_id}/report?limits=../../etc").status_code == 422
    with chromium(tmp_path / "profile") as driver:
        driver.get(f"{server.base_url}/results/{result_id}/report?limits=crouzet_82800502_eol")  # type: ignore[attr-defined]
        images = driver.find_elements(By.TAG_NAME, "img")  # type: ignore[attr-defined]
        assert len(images) == 1  # the one input run, drawn with the result
        assert all(int(img.get_property("naturalWidth")) >= 600 for img in images)
        # identify gives Kt/J, not Kt: an end-of-line limit on Kt is not measured, so FAIL.
        assert driver.find_element(By.ID, "eol").text == "FAIL"  # type: ignore[attr-defined]
        assert "Kt_over_J" in driver.page_source  # type: ignore[attr-defined]

        driver.get(server.base_url + "/")  # type: ignore[attr-defined]
        find = driver.find_element  # type: ignore[attr-defined]
        wait_for(lambda: find(By.TAG_NAME, "body").get_attribute("data-ready"), what="page ready")
        click_row(driver, "results", result_id)
        driver.switch_to.frame(find(By.ID, "result-frame"))  # type: ignore[attr-defined]
        framed = wait_for(lambda: driver.find_elements(By.TAG_NAME, "img"), what="report in frame")  # type: ignore[attr-defined]
        wait_for(lambda: int(framed[0].get_property("naturalWidth")) > 0, what="figure drawn")
