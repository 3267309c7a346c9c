"""The Author page: palette, drag-and-drop, typed forms, live lint, saving XML that runs.

The authored procedure runs in the web view against the real robot side (``caretaker up --scene
iva``): the arm really pulls the filter the operator names out of the rack.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from author_page import bind_arg, card, drop, set_arg, set_attr
from playwright.sync_api import Page, expect

from console.authoring import check_document, read_document
from console.procedure_view import procedure_json
from pride.parser import load_procedure
from pride.sysrep import load_sysrep_dir
from support.operator_page import expect_current, instruction, screenshot
from support.web_server import REPO, WebServer, server_on_real_stack

SHIPPED = sorted(p.name for p in (REPO / "procedures").glob("*.xml"))


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, ros_env: dict[str, str]) -> Iterator[WebServer]:
    """A web server on the real IVA stack, with a procedure shelf of its own to save into."""
    tmp = tmp_path_factory.mktemp("author")
    shelf = tmp / "procedures"
    shutil.copytree(REPO / "procedures", shelf)
    with server_on_real_stack(tmp, shelf, ros_env) as served:
        yield served


@pytest.mark.parametrize("name", SHIPPED)
def test_opening_and_saving_a_shipped_procedure_changes_nothing(name: str, tmp_path: Path) -> None:
    source = REPO / "procedures" / name
    for sibling in (REPO / "procedures").glob("*.xml"):  # calls resolve next to the saved file
        (tmp_path / sibling.name).symlink_to(sibling)
    checked = check_document(read_document(source), tmp_path, load_sysrep_dir(REPO / "sysrep"))
    assert checked["problems"] == []
    saved = tmp_path / f"saved_{name}"
    saved.write_text(checked["xml"])
    assert procedure_json(load_procedure(saved)) == procedure_json(load_procedure(source))


def test_author_a_procedure_by_drag_and_drop_save_it_and_run_it(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    alice.goto(f"{server.url}/author")
    expect(alice.locator("#check-state")).to_have_text("1 problem(s)")  # a new procedure's empty step
    expect(alice.locator("#canvas .canvas-step .problem")).to_have_count(1)
    for field, value in (("#proc-id", "authored_pick"), ("#proc-title", "Pick a filter (authored in the browser)")):
        alice.fill(field, value)
        alice.press(field, "Tab")
    alice.locator('#proc-uses input[value="affordance_templates"]').check()
    at = '#palette-sysreps section[data-sysrep="affordance_templates"]'

    # add the template, keeping its instance as the result "at"
    drop(alice, f'{at} li[data-command="add_affordance_template"]', 0)
    set_arg(alice, "1.1", "affordance_template", "cdra_filter")
    set_attr(alice, "1.1", "result", "at")
    # the operator records the frame to pick from
    drop(alice, '#palette-kinds li[data-kind="record"]', 1)
    set_attr(alice, "1.2", "name", "pick_frame")
    card(alice, "1.2").locator(".item-text").fill("Frame of the filter to pick (e.g. filter/CDRA-F-0012)")
    card(alice, "1.2").locator(".item-text").press("Tab")
    # register the AT there: the id from the result, the frame from the recorded input
    drop(alice, f'{at} li[data-command="set_display_object_pose"]', 2)
    set_arg(alice, "1.3", "affordance_template", "cdra_filter")
    bind_arg(alice, "1.3", "id", "${at.id}")
    set_arg(alice, "1.3", "display_object", "cdra_filter")
    bind_arg(alice, "1.3", "frame", "${pick_frame}")
    expect(card(alice, "1.3").locator('.arg[data-arg="x"] .arg-value')).to_have_attribute("type", "number")
    # plan, verify the plan, execute
    drop(alice, f'{at} li[data-command="plan_trajectory"]', 3)
    set_arg(alice, "1.4", "affordance_template", "cdra_filter")
    set_arg(alice, "1.4", "trajectory", "grasp_and_pull")
    drop(alice, f'{at} li[data-telemetry="plan_valid"]', 4)
    expect(card(alice, "1.5")).to_have_class(re.compile(r"\bhas-problem\b"))  # a verify needs a test
    set_attr(alice, "1.5", "equals", "true")
    drop(alice, f'{at} li[data-command="execute_plan"]', 5)
    set_arg(alice, "1.6", "affordance_template", "cdra_filter")
    set_arg(alice, "1.6", "trajectory", "grasp_and_pull")

    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    expect(alice.locator("#canvas .card.has-problem")).to_have_count(0)
    screenshot(alice, "web_author.png")
    alice.fill("#save-name", "authored_pick.xml")
    alice.click("#save")
    expect(alice.locator("#check-state")).to_have_text("saved authored_pick.xml")

    saved = server.procedures / "authored_pick.xml"
    lint = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "lint", str(saved)], capture_output=True, text=True, timeout=60
    )
    assert lint.returncode == 0, lint.stdout + lint.stderr
    assert "${pick_frame}" in saved.read_text()

    # and it runs in the web view
    alice.goto(server.url)
    alice.select_option("#start-procedure", "authored_pick.xml")
    alice.select_option("#start-binding", "iva.yaml")
    alice.check("#start-form input[name=mode][value=autonomous]")
    alice.click("#start-button")
    record = instruction(alice, "1.2")
    expect_current(record)
    record.locator("input.record-value").fill("filter/CDRA-F-0012")
    record.locator("button.record").click()
    expect(alice.locator("#run-status")).to_have_text("completed", timeout=120_000)
    expect(instruction(alice, "1.3").locator(".raw-detail")).to_contain_text("frame=filter/CDRA-F-0012")
    expect(instruction(alice, "1.6").locator(".detail")).to_contain_text("SUCCEEDED")
