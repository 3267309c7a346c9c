"""Editing on the Author page: cards move by dragging, a call's arguments follow what it calls;
outputs, sets, call results and monitors open as forms, save unchanged, and are made in them with
live lint at their place; each step says what a run started there would need.

Runs against the web server on simulated systems (conftest.py): authoring needs only the SysReps
and the procedure shelf, and what is saved is read back from the server's disk. The monitors'
tests use the lab bench's SysRep (its temperature has limits; no shipped item has) on a server
of their own.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator

import pytest
from author_page import bind_arg, card, drop, drop_zone, meaning, select_attr, set_arg, set_attr
from playwright.sync_api import Locator, Page, expect

from procedure_language.limits import Persistence
from procedure_language.model import CallInstruction, CommandInstruction, Condition, SetInstruction, Template
from procedure_language.parser import load_procedure
from support.procedures import FIXTURES
from support.web_server import WebServer, start_server

#: The lab bench's procedures: monitors, outputs and sets, call results; and monitors lint refuses.
LAB_SHELF = ["lab_monitors.xml", "lab_outputs.xml", "lab_locate.xml", "broken/monitor_problems.xml"]


@pytest.fixture(scope="module")
def lab_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    """A server on the lab bench's SysRep, its shelf the lab procedures (saved copies land there)."""
    tmp = tmp_path_factory.mktemp("author_lab")
    shelf = tmp / "procedures"
    shelf.mkdir()
    for name in LAB_SHELF:
        (shelf / name.split("/")[-1]).symlink_to(FIXTURES / name)
    served = start_server(tmp, shelf, sysreps=FIXTURES / "sysrep")
    yield served
    served.process.stop()


def tall_page(sign_in: Callable[[str], Page]) -> Page:
    """Alice's page, tall enough that drag and drop stay in view: a synthetic drag does not scroll."""
    page = sign_in("alice")
    page.set_viewport_size({"width": 1500, "height": 1600})
    return page


def open_procedure(page: Page, name: str, state: str = "lint: no problems") -> None:
    page.fill("#save-name", "")  # the page names the file there once its document is in, its check begun
    page.select_option("#open-name", name)
    page.click("#open")
    expect(page.locator("#save-name")).to_have_value(name)
    expect(page.locator("#check-state")).to_have_text(state)


def save_as(page: Page, name: str) -> None:
    page.fill("#save-name", name)
    page.click("#save")
    expect(page.locator("#check-state")).to_have_text(f"saved {name}")


def monitors(page: Page, step: int) -> Locator:
    """The monitor cards of a step (monitors are no instructions: they have no number)."""
    return page.locator(f'#canvas .canvas-step[data-step="{step}"] .card[data-kind="monitor"]')


def section_start(page: Page, step: int) -> Locator:
    return page.locator(f'#canvas .canvas-step[data-step="{step}"] .section-start')


def xml(page: Page) -> str:
    expect(page.locator("#check-state")).not_to_have_text("checking…")
    return page.locator("#xml").text_content() or ""


def header(number: str) -> str:
    """A card's header: the handle it is dragged by."""
    return f'#canvas .card[data-number="{number}"] > header'


@pytest.mark.parametrize(
    "server", ["sqlite"], indirect=True
)  # the page only: the log is tested on both databases elsewhere
def test_a_card_dragged_by_its_header_moves_within_and_across_steps(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = tall_page(sign_in)
    alice.goto(f"{server.url}/author")
    open_procedure(alice, "eva_inspection.xml")
    before = xml(alice)
    assert before.index('"affordance_template_server_active"') < before.index('"planner_node_active"')

    alice.drag_and_drop(header("1.2"), drop_zone(0, 0))
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    after = xml(alice)
    assert after.index('"planner_node_active"') < after.index('"affordance_template_server_active"')

    # into another step: the first step's last card goes before the second step's call
    alice.drag_and_drop(header("1.5"), drop_zone(1, 0))
    expect(alice.locator('#canvas .canvas-step[data-step="0"] .card')).to_have_count(5)
    expect(alice.locator('#canvas .canvas-step[data-step="1"] .card')).to_have_count(2)
    expect(card(alice, "2.1")).to_contain_text("affordance_templates.set_display_object_pose")
    expect(card(alice, "2.2")).to_have_attribute("data-kind", "call")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")


@pytest.mark.parametrize(
    "server", ["sqlite"], indirect=True
)  # the page only: the log is tested on both databases elsewhere
def test_a_step_dragged_by_its_handle_moves_and_everything_renumbers(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = tall_page(sign_in)
    alice.goto(f"{server.url}/author")
    open_procedure(alice, "eva_inspection.xml")
    assert xml(alice).index('id="hull_a"') < xml(alice).index('id="hull_b"')
    alice.drag_and_drop('#canvas .canvas-step[data-step="2"] .handle', '#canvas .step-drop[data-step-index="1"]')
    expect(alice.locator('#canvas .canvas-step[data-step="1"] .step-id')).to_have_value("hull_b")
    expect(alice.locator('#canvas .canvas-step[data-step="2"] .step-id')).to_have_value("hull_a")
    expect(card(alice, "2.1").locator('.arg[data-arg="target"] .arg-value')).to_have_value("hull_b")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    after = xml(alice)
    assert after.index('id="hull_b"') < after.index('id="hull_a"') < after.index('id="hull_c"')


@pytest.mark.parametrize(
    "server", ["sqlite"], indirect=True
)  # the page only: the log is tested on both databases elsewhere
def test_a_call_gets_the_inputs_of_the_procedure_it_names_and_its_arguments_can_be_edited(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = tall_page(sign_in)
    alice.goto(f"{server.url}/author")
    open_procedure(alice, "eva_inspection.xml")

    # a new call in step 2: naming the procedure gives a typed row per declared input
    drop(alice, '#palette-kinds li[data-kind="call"]', 1, step=1)
    set_attr(alice, "2.2", "procedure", "eva_inspect_target.xml")
    call = card(alice, "2.2")
    expect(call.locator(".arg")).to_have_count(2)
    expect(call.locator('.arg[data-arg="template_id"] .arg-value')).to_have_attribute("type", "number")
    set_arg(alice, "2.2", "target", "hull_e")
    bind_arg(alice, "2.2", "template_id", "${inspection_at.id}")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")

    # an argument the callee does not declare: named on the page, refused by lint, then removed
    call.get_by_role("button", name="add an argument").click()
    name = call.locator(".arg .arg-name")
    name.fill("colour")
    name.press("Tab")
    expect(call).to_have_class(re.compile(r"\bhas-problem\b"))
    expect(call.locator(".problem")).to_contain_text("unknown input 'colour'")
    call.get_by_role("button", name="remove argument colour").click()
    # the page is valid again; its lint result redraws the card (the problem line goes), so the
    # next click waits for that instead of landing where the layout was
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    # a declared one removed is missed; added back by name, it is typed again
    call.get_by_role("button", name="remove argument target").click()
    expect(call.locator(".problem")).to_contain_text("missing input 'target'")
    call.get_by_role("button", name="add an argument").click()
    name.fill("target")
    name.press("Tab")
    set_arg(alice, "2.2", "target", "hull_e")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")

    alice.fill("#save-name", "inspect_five.xml")
    alice.click("#save")
    expect(alice.locator("#check-state")).to_have_text("saved inspect_five.xml")
    saved = (server.procedures / "inspect_five.xml").read_text()
    assert re.search(
        r'<call procedure="eva_inspect_target.xml">\s*<arg name="template_id">\$\{inspection_at.id\}</arg>\s*'
        r'<arg name="target">hull_e</arg>\s*</call>',
        saved,
    ), saved


def test_outputs_sets_call_results_and_monitors_open_as_forms_and_save_as_they_were(
    open_page: Callable[[WebServer, str], Page], lab_server: WebServer
) -> None:
    alice = open_page(lab_server, "alice")
    alice.set_viewport_size({"width": 1500, "height": 1600})
    alice.goto(f"{lab_server.url}/author")

    open_procedure(alice, "lab_monitors.xml")
    red, door = monitors(alice, 0).nth(0), monitors(alice, 0).nth(1)
    for field, value in (
        ("system", "lab"),
        ("telemetry", "temperature"),
        ("limit", "red"),
        ("on-violation", "goto:cool"),
    ):
        expect(red.locator(f'select[data-attr="{field}"]')).to_have_value(value)
    expect(red.locator('select[data-attr="limit"] option[value="red"]')).to_have_text("red above 40")
    expect(red.locator("select[data-field=watch]")).to_have_value("limit")
    expect(red.locator(".item-sentence")).to_have_value("The bench stays below its red temperature")
    expect(door.locator("select[data-field=watch]")).to_have_value("condition")
    expect(door.locator('[data-attr="equals"]')).to_have_value("false")
    expect(door.locator('select[data-attr="on-violation"]')).to_have_value("hold")
    expect(alice.locator('#canvas .canvas-step[data-step="1"] .contingency input')).to_be_checked()
    expect(section_start(alice, 0)).to_have_text("a run may start here: --from move")
    expect(section_start(alice, 1)).to_have_text("a run may start here: --from cool")

    open_procedure(alice, "lab_locate.xml")
    rows = alice.locator("#proc-outputs .declared")
    expect(rows).to_have_count(2)
    expect(rows.nth(0).locator(".declared-name")).to_have_value("total")
    expect(rows.nth(0).locator('select[data-attr="type"]')).to_have_value("integer")
    expect(alice.locator("#proc-inputs .declared .declared-name")).to_have_value("n")
    expect(card(alice, "2.1").locator('select[data-attr="name"]')).to_have_value("total")
    expect(card(alice, "2.1").locator('.arg[data-arg="value"] .arg-value')).to_have_value("${counted.total}")
    expect(card(alice, "2.1").locator('.arg[data-arg="value"] .arg-bind')).to_have_value("${counted.total}")
    expect(card(alice, "2.2").locator(".item-sentence")).to_have_value("The arm goes to the dock")
    # only step 1 binds counted: a start at found must be given it; lost sets literals
    expect(section_start(alice, 1)).to_have_text(
        "a start here (--from found) must be given counted.total (read at 2.1) with --set NAME=VALUE"
    )
    expect(section_start(alice, 1)).to_have_attribute("data-ok", "false")
    expect(section_start(alice, 2)).to_have_text("a run may start here: --from lost")

    open_procedure(alice, "lab_outputs.xml")
    expect(card(alice, "1.2").locator('[data-attr="result"]')).to_have_value("second")
    bind = card(alice, "1.3").locator('.arg[data-arg="target"] .arg-bind')  # the outputs lab_locate declares
    expect(bind.locator("option")).to_contain_text(["${first.total}", "${first.where}", "${second.where}"])

    # each saved without an edit is the procedure it was
    for name in ("lab_monitors.xml", "lab_locate.xml", "lab_outputs.xml"):
        open_procedure(alice, name)
        save_as(alice, f"same_{name}")
        saved, source = lab_server.procedures / f"same_{name}", lab_server.procedures / name
        assert meaning(load_procedure(saved)) == meaning(load_procedure(source)), saved.read_text()

    # monitors lint refuses, each with its problem on its card; what the file names stays chosen
    open_procedure(alice, "monitor_problems.xml", "4 problem(s)")
    refused = monitors(alice, 0)
    for n, said in enumerate(
        (
            "unknown telemetry 'temprature' in lab",
            "min compares numbers; lab.door_open is boolean",
            "lab.state has no limits in its SysRep",
            "go-to to nowhere: no step 'cooldwn'",
        )
    ):
        expect(refused.nth(n)).to_have_class(re.compile(r"\bhas-problem\b"))
        expect(refused.nth(n).locator(".problem")).to_contain_text(said)
    expect(refused.nth(0).locator('select[data-attr="telemetry"]')).to_have_value("temprature")
    expect(refused.nth(3).locator('select[data-attr="on-violation"]')).to_have_value("goto:cooldwn")
    expect(section_start(alice, 0)).to_have_text("a start here (--from): shown when lint finds no problem")


def test_outputs_sets_call_results_and_monitors_made_in_the_forms_are_linted_in_place_and_saved(
    open_page: Callable[[WebServer, str], Page], lab_server: WebServer
) -> None:
    alice = open_page(lab_server, "alice")
    alice.set_viewport_size({"width": 1500, "height": 1600})
    alice.goto(f"{lab_server.url}/author")
    open_procedure(alice, "lab_monitors.xml")

    # an output: unset on the paths that end the procedure, said on its row
    alice.get_by_role("button", name="add an output").click()
    output = alice.locator("#proc-outputs .declared")
    output.locator(".declared-name").fill("where")
    output.locator(".declared-name").press("Tab")
    expect(output.locator(".problem")).to_contain_text("output 'where' is not set on every path that ends lab_monitors")

    # a call keeps its result; a set in step 1 gives the output one of the callee's outputs
    drop(alice, '#palette-kinds li[data-kind="call"]', 2)  # after the two monitors: instruction 1.1
    set_attr(alice, "1.1", "procedure", "lab_locate.xml")
    set_arg(alice, "1.1", "n", "2")
    set_attr(alice, "1.1", "result", "look")
    drop(alice, '#palette-kinds li[data-kind="set"]', 5)
    expect(card(alice, "1.4").locator('select[data-attr="name"]')).to_have_value("where")
    bind_arg(alice, "1.4", "value", "${look.where}")
    # the red limit may go to cool, which ends the procedure: not set there
    expect(output.locator(".problem")).to_contain_text("not set when it ends after 2.1")
    drop(alice, '#palette-kinds li[data-kind="set"]', 1, step=1)
    bind_arg(alice, "2.2", "value", "${look.where}")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    expect(output).not_to_have_class(re.compile(r"\bhas-problem\b"))
    # a start at cool skips the call it reads from; with a literal it needs nothing
    expect(section_start(alice, 1)).to_have_text(
        "a start here (--from cool) must be given look.where (read at 2.2) with --set NAME=VALUE"
    )
    bind_arg(alice, "2.2", "value", "")
    set_arg(alice, "2.2", "value", "home")
    expect(section_start(alice, 1)).to_have_text("a run may start here: --from cool")

    # reading an output the callee does not declare: said on the card that reads it
    set_arg(alice, "1.3", "label", "${look.place}")
    expect(card(alice, "1.3").locator(".problem")).to_contain_text("lab_locate declares no output 'place'")
    bind_arg(alice, "1.3", "label", "${look.where}")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")

    # a new monitor: the used SysRep's item with limits, watched against its red limit; the pickers
    # choose another item, the limit it must have, or a condition typed by the item
    drop(alice, '#palette-kinds li[data-kind="monitor"]', 0)
    watch = monitors(alice, 0).nth(0)
    expect(watch.locator('select[data-attr="telemetry"]')).to_have_value("temperature")
    expect(watch.locator('select[data-attr="limit"]')).to_have_value("red")
    select_attr(alice, watch, "telemetry", "door_open")
    expect(watch.locator(".problem")).to_contain_text("lab.door_open has no limits in its SysRep")
    watch.locator("select[data-field=watch]").select_option("condition")
    expect(watch.locator(".problem")).to_contain_text("<monitor> watches a condition")
    set_attr(alice, watch, "min", "1")
    expect(watch.locator(".problem")).to_contain_text("min compares numbers; lab.door_open is boolean")
    select_attr(alice, watch, "telemetry", "temperature")
    set_attr(alice, watch, "min", "")
    set_attr(alice, watch, "max", "hot")
    expect(watch.locator(".problem")).to_contain_text("lab.temperature is real")
    set_attr(alice, watch, "max", "35")
    select_attr(alice, watch, "scope", "procedure")
    select_attr(alice, watch, "on-violation", "goto:cool")
    set_attr(alice, watch, "persistence", "3")
    watch.locator(".item-sentence").fill("The bench stays below 35 degrees")
    watch.locator(".item-sentence").press("Tab")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")

    save_as(alice, "lab_monitors_edited.xml")
    saved = load_procedure(lab_server.procedures / "lab_monitors_edited.xml")
    assert [(o.name, o.type) for o in saved.outputs] == [("where", "string")]
    first, second = saved.steps
    watched = first.monitors[0]
    assert (watched.system, watched.telemetry, watched.condition, watched.limit) == (
        "lab",
        "temperature",
        Condition(maximum="35"),
        None,
    )
    assert (watched.scope, watched.on_violation, watched.goto, watched.persistence, watched.text) == (
        "procedure",
        "goto",
        "cool",
        Persistence(samples=3),
        "The bench stays below 35 degrees",
    )
    assert len(first.monitors) == 3  # and the two it had
    call, _, capture, set_where = first.instructions
    assert isinstance(call, CallInstruction) and (call.procedure, call.result) == ("lab_locate.xml", "look")
    assert isinstance(capture, CommandInstruction) and capture.args[0].value == Template.parse("${look.where}")
    assert isinstance(set_where, SetInstruction) and set_where.value == Template.parse("${look.where}")
    (set_home,) = (i for i in second.instructions if isinstance(i, SetInstruction))
    assert (set_home.name, set_home.value) == ("where", Template.parse("home"))
