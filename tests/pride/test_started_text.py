"""A started instruction reads with the values the run knew then: in the log, the report and the terminal.

The started event keeps the author's sentence (``text``, with its ``${...}``) and adds it filled in
(``text_filled``); everything that shows a started event to people shows the filled one, and for a
log recorded before events carried it, the author's text with its values said to be not known.
"""

from __future__ import annotations

import io
from datetime import UTC, datetime

from caretaker.terminal import ProgressPrinter, TerminalLines
from pride.event_words import describe_event, started_text
from pride.events import Event, EventKind
from pride.executive import Hold, Mode, RunStatus
from pride.phrasing import fill_text
from pride.report import summarize, to_html, to_markdown
from procedure_language.model import Template
from support.executive_runs import Bench, finished, held

FILTER = "CDRA-F-0012"


def test_the_report_and_the_terminal_show_a_started_sentence_with_the_values_known_then(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS, "lab_filled_text.xml", run_id="filled")
    terminal = io.StringIO()
    executive.add_listener(ProgressPrinter(executive.procedure, TerminalLines(terminal)))
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.1")
    executive.enter("alice", FILTER)
    held(executive, Hold.OPERATOR_ACTION, "1.3")
    executive.mark_done("alice")
    assert finished(executive).status is RunStatus.COMPLETED
    executive.join(20)

    events = journal.log.events("filled")  # as stored: through the database and back
    started = {e.instruction: e.data.to_json() for e in events if e.kind is EventKind.INSTRUCTION_STARTED}
    assert started["1.2"]["text"] == "Pick clean filter ${clean_filter_id} from the rack"  # the author's, as written
    assert started["1.2"]["text_filled"] == f"Pick clean filter {FILTER} from the rack"

    summary = summarize(events)
    for report in (to_html(summary), to_markdown(summary)):
        assert f"started: Pick clean filter {FILTER} from the rack" in report
        assert f"waiting for an operator: 1.3: Check that filter {FILTER} arrived (arrived: true)" in report
        assert "${" not in report
    printed = terminal.getvalue()
    assert f"Pick clean filter {FILTER} from the rack" in printed
    assert f"Check that filter {FILTER} arrived (arrived: true)" in printed
    assert "${" not in printed


def test_a_value_not_known_yet_stays_a_reference_for_authors_and_reads_as_words_for_operators() -> None:
    sentence = Template.parse("Put ${filter} in ${slot.name} at ${slot.depth} m (${later})")
    env = {"filter": "CDRA-F-0012", "slot": {"name": "B", "depth": 0.30000000000000004}}
    assert sentence.fill(env) == "Put CDRA-F-0012 in B at 0.30000000000000004 m (${later})"
    assert sentence.fill({"slot": {}}) == "Put ${filter} in ${slot.name} at ${slot.depth} m (${later})"
    assert fill_text(str(sentence), env) == "Put CDRA-F-0012 in B at 0.3 m (‹later: not known yet›)"


def test_a_started_event_logged_before_it_carried_the_filled_text_reads_as_the_authors_text_in_words() -> None:
    old = Event(
        "r",
        5,
        EventKind.INSTRUCTION_STARTED,
        "PAX",
        "4.3",
        {"instruction_kind": "command", "text": "Pick clean filter ${clean_filter_id} from the rack"},
        datetime(2024, 1, 1, tzinfo=UTC),
    )
    said = "Pick clean filter ‹clean filter id: not known yet› from the rack"  # the record does not hold it
    assert started_text(old) == said
    assert describe_event(old) == f"started: {said}"
    new = Event(
        "r",
        5,
        EventKind.INSTRUCTION_STARTED,
        "PAX",
        "4.3",
        {**old.data.to_json(), "text_filled": "Pick clean filter X"},
        old.time,
    )
    assert describe_event(new) == "started: Pick clean filter X"
