"""Editing on the Author page: cards move by dragging, a call's arguments follow what it calls.

Runs against the web server on simulated systems (conftest.py): authoring needs only the SysReps
and the procedure shelf, and what is saved is read back from the server's disk.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import pytest
from author_page import bind_arg, card, drop, drop_zone, set_arg, set_attr
from playwright.sync_api import Page, expect

from support.web_server import WebServer


def tall_page(sign_in: Callable[[str], Page]) -> Page:
    """Alice's page, tall enough that drag and drop stay in view: a synthetic drag does not scroll."""
    page = sign_in("alice")
    page.set_viewport_size({"width": 1500, "height": 1600})
    return page


def open_procedure(page: Page, name: str) -> None:
    page.select_option("#open-name", name)
    page.click("#open")
    expect(page.locator("#check-state")).to_have_text("lint: no problems")


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
