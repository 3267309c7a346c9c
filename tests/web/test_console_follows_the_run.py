"""The console a flight controller reads: sentences, a page that follows the run, telemetry against its limits.

On the simulated systems (simulated_systems.py), through a server of this module's own whose
SysReps give ``cdra.installed_filter_id`` an enum and add the test bench (fixtures/sysrep: a plate
with yellow and red limits, on a binding of its own; the shipped SysReps carry no limits), so
values outside their limits and the Monitors panel can be shown.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable, Iterator

import pytest
from playwright.sync_api import Page, expect

from procedure_language.model import CallInstruction
from procedure_language.parser import load_procedure
from support.operator_page import (
    IVA,
    expect_current,
    instruction,
    screenshot,
    start_run,
    stop_run,
    unlock_approved_by,
)
from support.web_server import REPO, WEB, WebServer, procedure_shelf, start_server

RAW_COMMAND = re.compile(r"\b[a-z_]+\.[a-z_]+\(")


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    tmp = tmp_path_factory.mktemp("console")
    sysreps = tmp / "sysrep"
    shutil.copytree(REPO / "sysrep", sysreps)
    cdra = sysreps / "cdra.yaml"
    text = cdra.read_text()
    known = "{description: empty when no filter is installed}"
    assert known in text
    cdra.write_text(text.replace(known, "{description: the filter's label, enum: [CDRA-F-0012, CDRA-F-0013]}"))
    shutil.copytree(WEB / "fixtures" / "sysrep", sysreps, dirs_exist_ok=True)  # the bench and its binding
    served = start_server(tmp, procedure_shelf(tmp), sysreps=sysreps, options=["--bindings", str(sysreps / "bindings")])
    yield served
    served.process.stop()


def sentences(page: Page) -> dict[str, str]:
    """Every instruction's main text as the page shows it, by number."""
    return page.evaluate("""() => Object.fromEntries([...document.querySelectorAll('#procedure li.instruction')]
        .map((item) => [item.dataset.number, item.querySelector(':scope > .line > .text').textContent]))""")


def assert_readable(texts: dict[str, str]) -> None:
    for number, text in texts.items():
        assert text.strip() and "${" not in text and not RAW_COMMAND.search(text), f"{number} reads as code: {text!r}"


def test_every_instruction_of_the_shipped_procedures_reads_as_a_sentence(sign_in: Callable[[str], Page]) -> None:
    alice = sign_in("alice")
    start_run(alice, IVA, "manual")
    texts = sentences(alice)
    iva = load_procedure(REPO / "procedures" / IVA)
    called = [
        load_procedure(REPO / "procedures" / i.procedure) for i in iva.instructions if isinstance(i, CallInstruction)
    ]
    assert len(texts) == len(iva.instructions) + sum(len(c.instructions) for c in called)  # each call draws its own
    assert_readable(texts)
    assert texts["2.2"] == "Plan the grasp-and-pull trajectory for cdra_filter:‹cdra_at.id›"  # not known yet

    # once PAX has added the template, its instance id is in every sentence that names it
    alice.click("#mode-autonomous")
    unlock_approved_by(alice, "bob")
    expect(alice.locator("#hold")).to_contain_text("2.6: Confirm that the area in front of the CDRA cabinet is clear")
    texts = sentences(alice)
    assert_readable(texts)
    assert texts["2.2"] == "Plan the grasp-and-pull trajectory for cdra_filter:0"
    assert texts["7.5"] == "Remove the CDRA filter AT (cdra_filter:0)"
    assert texts["4.2"] == "Read which rack slot filter ‹clean_filter_id› is seated in"
    assert texts["1.13/2.1"] == "Locate rack slot 3 from its markers in the wrist camera"  # the caller's words
    expect(instruction(alice, "2.2").locator(".detail")).to_contain_text(
        "Result: succeeded — planned · Plan Status: PLANNED"
    )
    expect(instruction(alice, "2.2").locator(".detail")).to_contain_text(
        "end pose: position (620, -180, 950) mm, orientation (0, 90, 20.1)°"  # millimetres and degrees
    )
    stop_run(alice, "sentences checked")

    # the EVA inspection, with the sub-procedure each target calls: its input is known once it is called
    start_run(alice, "eva_inspection.xml", "manual", binding="eva.yaml")
    instruction(alice, "2.1/1.2").locator("button.breakpoint").click()
    expect(instruction(alice, "2.1/1.2")).to_have_class(re.compile(r"\bhas-breakpoint\b"))
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_contain_text("Breakpoint at 2.1/1.2")
    texts = sentences(alice)
    assert len(texts) == 17 + 4 * 20  # the four calls draw the sub-procedure each
    assert_readable(texts)
    assert texts["2.1/1.1"] == "Align the inspection AT with hull target hull_a"
    assert texts["3.1/1.1"] == "Align the inspection AT with hull target ‹target›"
    stop_run(alice, "sentences checked")

    # a procedure without <text>: its sentences come from the SysReps' labels
    start_run(alice, "web_walkthrough.xml", "manual")
    texts = sentences(alice)
    assert_readable(texts)
    assert texts == {
        "1.1": 'Add Affordance Template "cdra_filter" (hide waypoints: false)',
        "2.1": 'Plan Trajectory "ready" for ready_pose',
        "2.2": "Verify Installed Filter Condition is dirty",
        "3.1": "Confirm the area near the cabinet is clear",
        "3.2": "Unlock Filter",
        "3.3": "Verify Filter Locked is false",
    }
    stop_run(alice, "sentences checked")


def test_the_page_follows_the_run_to_a_hold_far_down_and_shows_who_watches(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob")
    expect_current(instruction(alice, "2.6"))
    expect(instruction(alice, "2.6")).to_be_in_viewport()
    instruction(alice, "2.6").locator("button.done").click()

    # PAX carries the arm through step 3 and holds at the record 4.1, far below: the page goes there
    record = instruction(alice, "4.1")
    expect_current(record)
    expect(record).to_be_in_viewport()
    expect(instruction(alice, "1.1")).not_to_be_in_viewport()
    hold = alice.locator("#hold")
    expect(hold).to_be_in_viewport()  # the banner stays at the top
    expect(hold).to_have_attribute("data-tone", "hold")
    expect(hold).to_contain_text("Needs a value")
    expect(hold).to_contain_text("4.1: Enter the id of a clean filter on the rack")
    expect(hold.locator(".hold-meta")).to_contain_text(
        re.compile(r"an operator must enter it \(operators watching: alice\) · since \d")
    )
    screenshot(alice, "web_hold_followed.png")

    # someone opening the run now lands on the hold as well, and both see who watches
    carol = sign_in("carol")
    carol.goto(f"{server.url}/#run={run_id}")
    expect(instruction(carol, "4.1")).to_be_in_viewport()
    for page in (alice, carol):
        expect(page.locator("#watchers")).to_have_text("watching: alice (operator), carol (observer)")
    carol.context.close()
    expect(alice.locator("#watchers")).to_have_text("watching: alice (operator)")

    # following can be switched off: then the page stays where the operator reads
    alice.uncheck("#follow")
    alice.evaluate("window.scrollTo(0, 0)")
    alice.evaluate(
        "act('enter', {instruction: '4.1', value: 'CDRA-F-0012'})"
    )  # the Record button, without scrolling to it
    expect(instruction(alice, "4.2").locator(".line > .text")).to_have_text(
        "Read which rack slot filter CDRA-F-0012 is seated in"
    )
    expect_current(instruction(alice, "5.1"))
    expect(instruction(alice, "5.1")).not_to_be_in_viewport()
    assert alice.evaluate("window.scrollY") == 0
    stop_run(alice, "followed")


def test_telemetry_is_coloured_by_its_limits_and_expectation_and_a_verify_counts_down(
    sign_in: Callable[[str], Page],
) -> None:
    alice = sign_in("alice")
    start_run(alice, "web_console.xml", "manual")
    out, ok, unexpected = (instruction(alice, n).locator(".telemetry") for n in ("1.1", "1.2", "1.3"))
    expect(out).to_have_attribute("data-state", "out")  # red: F-DIRTY-07 is not a filter id the SysRep knows
    expect(out).to_contain_text("⚠ Installed Filter ID = F-DIRTY-07 (outside its limits: 'F-DIRTY-07' is not one of")
    expect(ok).to_have_attribute("data-state", "ok")
    expect(ok).to_contain_text("✓ Affordance Template Server Active = true")
    expect(unexpected).to_have_attribute("data-state", "unexpected")  # locked, where the verify wants it unlocked
    expect(unexpected).to_contain_text("≠ Filter Locked = true (expected false)")
    colours = {
        n: instruction(alice, n).locator(".telemetry").evaluate("chip => getComputedStyle(chip).backgroundColor")
        for n in ("1.1", "1.2", "1.3")
    }
    assert len(set(colours.values())) == 3, colours

    # PAX checks the first two and waits for the latch: the verify counts down its 60 s
    alice.click("#mode-autonomous")
    countdown = instruction(alice, "1.3").locator(".countdown")
    expect(countdown).to_have_text(re.compile(r"^◷ \d+ s left of 60 s$"))
    first = int(countdown.inner_text().split()[1])
    assert 0 < first <= 60
    expect(countdown).not_to_have_text(f"◷ {first} s left of 60 s")
    assert int(countdown.inner_text().split()[1]) < first
    stop_run(alice, "countdown seen")
    expect(countdown).to_have_text("")


def test_monitors_and_values_show_their_limits_in_colour_and_in_words(sign_in: Callable[[str], Page]) -> None:
    """The bench plate heated through its bands (yellow above 40, red above 50) while a monitor
    watches its red limit: the Monitors panel, the verify's live value and the value it decided
    on say green, yellow or red in colour and in words; a violation and its clear come from the
    record, so the past run shows them too."""
    alice = sign_in("alice")
    start_run(alice, "web_monitors.xml", "manual", binding="bench.yaml")
    monitor = alice.locator('#monitors li.monitor[data-monitor="bench.temperature (step 1)"]')
    value = monitor.locator(".monitor-value .limit-value")
    chip = instruction(alice, "1.4").locator(".line > .telemetry")  # the verify's live value
    expect(monitor.locator(".monitor-text")).to_have_text("The plate stays below its red temperature")
    expect(monitor.locator(".monitor-meta")).to_have_text("step 1 · when violated, the run holds")
    colours: dict[str, tuple[str, ...]] = {}

    def crossed(limit: str, words: str, state: str, said: str) -> None:
        """The plate's value reads ``limit`` in the panel and on the verify, the monitor ``state``."""
        for shown in (value, chip):
            expect(shown).to_have_attribute("data-limit", limit)
            expect(shown).to_contain_text(f"Plate Temperature = {words}")
        expect(monitor).to_have_attribute("data-state", state)
        expect(monitor.locator(".monitor-state")).to_have_text(said)
        colours[limit] = tuple(
            node.evaluate("node => getComputedStyle(node).backgroundColor + ' ' + getComputedStyle(node).color")
            for node in (monitor, value, chip)
        )

    def send(number: str) -> None:
        instruction(alice, number).locator("button.perform").click()
        expect(instruction(alice, number)).to_have_attribute("data-status", "completed")

    crossed("green", "21 degC GREEN", "green", "✓ GREEN")
    send("1.1")  # 45
    crossed("yellow", "45 degC YELLOW HIGH (yellow above 40)", "yellow", "▲ YELLOW")
    send("1.2")  # 55: out of the monitor's red limit, violated: the run holds (automation pauses)
    crossed("red", "55 degC RED HIGH (red above 50)", "red", "⚠ RED · violated")
    news = monitor.locator(".monitor-news")
    expect(news).to_have_text(re.compile(r"^violated at .+: 55 \(red above 50\) · the run held$"))
    assert len({colours[limit] for limit in ("green", "yellow", "red")}) == 3, colours
    expect(alice.locator('#audit li[data-kind="monitor_violated"][data-actor="PAX"]')).to_have_count(1)
    screenshot(alice, "console-monitors.png")
    send("1.3")  # 30: back within, cleared
    crossed("green", "30 degC GREEN", "green", "✓ GREEN")
    expect(news).to_have_text(re.compile(r"^cleared at .+: 30$"))

    # the verify decides on the value as it was then, and its row keeps it with its limit state
    instruction(alice, "1.4").locator("button.perform").click()
    seen = instruction(alice, "1.4").locator(".detail .limit-value")
    expect(seen).to_have_text("saw Plate Temperature = 30 GREEN")
    expect(seen).to_have_attribute("data-limit", "green")
    send("1.5")  # 60: violated again
    expect(monitor).to_have_attribute("data-state", "red")
    again = r"^violated at .+: 60 \(red above 50\) · the run held · violated 2 times in this run$"
    expect(news).to_have_text(re.compile(again))

    # the past run, drawn from the record alone: the violation as it ended, no live value
    stop_run(alice, "limits seen")
    expect(monitor).to_have_attribute("data-state", "red")
    expect(monitor).to_have_attribute("data-active", "false")
    expect(news).to_contain_text("violated 2 times in this run")
    expect(value).to_have_count(0)
    expect(seen).to_have_attribute("data-limit", "green")
