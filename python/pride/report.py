"""After-action report of one run, from its audit records: HTML and Markdown.

Who did what when, how long each step took, the telemetry values verifies decided on, a
timeline (hand-made inline SVG: no plotting library), and the images captured during the run
(command results whose values carry an image ``path``; copied next to the report so it stays
complete when the run's files are cleaned up). Everything reads as the procedure view and the
audit panel read (:mod:`pride.phrasing`, with the SysReps' labels a :class:`Wording` holds);
the calls as sent only in a raw report (``caretaker report --raw``).
"""

from __future__ import annotations

import html
import shutil
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import assert_never

from pride import event_payloads as ep
from pride.event_words import describe_event, reading_words, version_text
from pride.events import PAX, Event, EventKind
from pride.phrasing import Wording

__all__ = ["RunSummary", "StepSummary", "summarize", "to_html", "to_markdown", "write_report"]

_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".gif", ".svg", ".webp"}
#: What a log that does not begin with its run's start is summarized from.
_NO_START = ep.RunStarted(procedure="", title="", version="", path="", mode="", robot="", steps=())


@dataclass
class StepSummary:
    """One step of the procedure as it went in this run; ``visits`` are (start, end) intervals."""

    number: int
    title: str
    visits: list[list[datetime]] = field(default_factory=list)
    completed: int = 0
    failed: int = 0
    skipped: int = 0
    actors: set[str] = field(default_factory=set)

    @property
    def seconds(self) -> float:
        return sum((end - start).total_seconds() for start, end in self.visits)


@dataclass
class Image:
    instruction: str
    time: datetime
    source: str
    label: str
    copied: str | None = None


@dataclass
class RunSummary:
    run_id: str
    procedure: str
    title: str
    version: str
    started: datetime
    ended: datetime
    started_by: str
    outcome: str
    steps: list[StepSummary]
    events: list[Event]
    telemetry: list[Event]
    images: list[Image]
    integrity: str = ""
    """What checking the run's hash chain found (empty: not checked)."""
    released: str = ""
    """The version it ran: its release, or a rehearsal (empty: recorded without one)."""
    section: str = ""
    """Where a run of part of the procedure started and stopped, in words (empty: the whole procedure)."""
    monitors: list[str] = field(default_factory=list)
    """What the run's monitors saw, in words: each violation (and the value's return), when and where."""

    @property
    def seconds(self) -> float:
        return (self.ended - self.started).total_seconds()


def summarize(events: list[Event]) -> RunSummary:
    """Fold a run's events into what the report shows."""
    start = events[0]
    started = start.data if isinstance(start.data, ep.RunStarted) else _NO_START
    steps = [StepSummary(number, title) for number, title in started.step_titles()]
    by_number = {s.number: s for s in steps}
    last_step: StepSummary | None = None
    for event in events:
        if not event.instruction:
            continue
        head = event.instruction.split("/")[0].split(".")[0]
        step = by_number.get(int(head)) if head.isdigit() else None
        if step is None:
            continue
        if step is not last_step or not step.visits:
            step.visits.append([event.time, event.time])
        step.visits[-1][1] = event.time
        last_step = step
        step.actors.add(event.actor)
    outcome = "interrupted"
    images: list[Image] = []
    telemetry: list[Event] = []
    monitors: list[str] = []
    for event in events:
        own = _own_step(event.instruction, by_number)  # a step's own instruction, not a sub-procedure's
        match event.data:
            case ep.InstructionCompleted() if own:
                own.completed += 1
            case ep.InstructionFailed() if own:
                own.failed += 1
            case ep.InstructionSkipped() if own:
                own.skipped += 1
            case ep.RunCompleted():
                outcome = "completed"
            case ep.RunStopped():
                outcome = "stopped"
            case ep.RunResumed():
                outcome = "interrupted"
            case ep.CommandResult(values=values) if Path(str(values.get("path", ""))).suffix.lower() in _IMAGE_SUFFIXES:
                path = str(values["path"])
                images.append(
                    Image(event.instruction or "", event.time, path, str(values.get("label") or Path(path).stem))
                )
            case ep.TelemetrySeen():
                telemetry.append(event)
            case ep.MonitorViolated() | ep.MonitorCleared():
                monitors.append(f"{event.time:%H:%M:%S} at {event.instruction or '—'}: {describe_event(event)}")
            case (
                ep.RunStarted()
                | ep.ModeChanged()
                | ep.InstructionStarted()
                | ep.InstructionCompleted()
                | ep.InstructionFailed()
                | ep.InstructionSkipped()
                | ep.InstructionHalted()
                | ep.CommandSent()
                | ep.CommandResult()
                | ep.OutcomeResolved()
                | ep.Halt()
                | ep.LinkLost()
                | ep.LinkRestored()
                | ep.ControlTaken()
                | ep.ControlLost()
                | ep.RecordCorrected()
                | ep.SteppedBack()
                | ep.OperatorInput()
                | ep.Confirmation()
                | ep.ApprovalRequested()
                | ep.ApprovalGiven()
                | ep.ApprovalExpired()
                | ep.ActionRefused()
                | ep.SupervisorAttached()
                | ep.AwaitingOperator()
                | ep.Paused()
                | ep.Continued()
                | ep.BreakpointSet()
                | ep.BreakpointCleared()
                | ep.BreakpointHit()
                | ep.Retry()
                | ep.CallEntered()
                | ep.ValueSet()
                | ep.CallReturned()
                | ep.WentTo()
            ):
                pass  # in the steps' counts and the actions table only
            case _:
                assert_never(event.data)
    return RunSummary(
        run_id=start.run_id,
        procedure=started.procedure,
        title=started.title,
        version=started.version,
        started=start.time,
        ended=events[-1].time,
        started_by=start.actor,
        outcome=outcome,
        steps=steps,
        events=events,
        telemetry=telemetry,
        images=images,
        released=version_text(started).removeprefix(" · "),
        section=_section_words(started),
        monitors=monitors,
    )


def _section_words(started: ep.RunStarted) -> str:
    """ "from step 4 (Finish) to step 4 (Finish)", with what was given for the steps skipped."""
    if not started.section:
        return ""
    numbers = {str(s.get("id")): (s.get("number"), s.get("title")) for s in started.steps}
    numbers.update({str(number): (number, title) for number, title in numbers.values()})

    def step(ref: object) -> str:
        number, title = numbers.get(str(ref), (ref, ""))
        return f"step {number} ({title})" if title else f"step {number}"

    words = f"started at {step(started.section.get('from'))}"
    if started.section.get("to"):
        words += f", to end after {step(started.section.get('to'))}"
    given = started.section.get("given") or {}
    if given:
        words += "; given for the steps before: " + ", ".join(f"{k} = {v}" for k, v in given.items())
    return words


def _own_step(number: str | None, by_number: dict[int, StepSummary]) -> StepSummary | None:
    """The step whose own instruction ``number`` is (None: none, or one of a sub-procedure)."""
    head = (number or "").split(".")[0]
    return by_number.get(int(head)) if head.isdigit() and number and "/" not in number else None


def _clock(moment: datetime) -> str:
    return moment.strftime("%H:%M:%S.") + f"{moment.microsecond // 1000:03d}"


def _duration(seconds: float) -> str:
    minutes, rest = divmod(seconds, 60)
    return f"{int(minutes)} min {rest:04.1f} s" if minutes else f"{rest:.1f} s"


def timeline_svg(summary: RunSummary, width: int = 860, wording: Wording | None = None) -> str:
    """Steps as rows, visits as bars on a shared time axis; operator actions and failures marked."""
    labels = [f"{step.number}. {step.title}" for step in summary.steps]
    # the label column fits the longest step title (about 7 px a character at 12 px): never clipped
    left, row, top = max(210, 16 + 7 * max(map(len, labels), default=0)), 26, 28
    width = max(width, left + 320)
    total = max(summary.seconds, 1e-3)
    scale = (width - left - 20) / total
    height = top + row * len(summary.steps) + 34

    def x(moment: datetime) -> float:
        return left + (moment - summary.started).total_seconds() * scale

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="12" role="img" '
        f'aria-label="Timeline of run {html.escape(summary.run_id)}">'
    ]
    for tick in range(6):
        seconds = total * tick / 5
        tx = left + seconds * scale
        parts.append(f'<line x1="{tx:.1f}" y1="{top - 6}" x2="{tx:.1f}" y2="{height - 28}" stroke="#ddd"/>')
        parts.append(f'<text x="{tx:.1f}" y="{height - 12}" text-anchor="middle" fill="#555">{seconds:.1f} s</text>')
    rows = {s.number: i for i, s in enumerate(summary.steps)}
    for i, step in enumerate(summary.steps):
        y = top + i * row
        parts.append(
            f'<text x="{left - 8}" y="{y + 15}" text-anchor="end" class="step-label">{html.escape(labels[i])}</text>'
        )
        color = "#c0392b" if step.failed and not step.completed else "#2e86c1" if step.visits else "#bbb"
        for start, end in step.visits:
            w = max((end - start).total_seconds() * scale, 2)
            parts.append(
                f'<rect x="{x(start):.1f}" y="{y + 4}" width="{w:.1f}" height="{row - 10}" rx="3" fill="{color}">'
                f"<title>step {step.number}: {_duration((end - start).total_seconds())}</title></rect>"
            )
    for event in summary.events:
        head = (event.instruction or "").split("/")[0].split(".")[0]
        if not head.isdigit() or int(head) not in rows:
            continue
        y = top + rows[int(head)] * row
        if event.kind is EventKind.INSTRUCTION_FAILED:
            parts.append(
                f'<circle cx="{x(event.time):.1f}" cy="{y + row / 2 - 1:.1f}" r="4" fill="#e74c3c">'
                f"<title>{html.escape(event.instruction or '')} failed</title></circle>"
            )
        elif event.actor != PAX and event.kind in (
            EventKind.OPERATOR_INPUT,
            EventKind.INSTRUCTION_COMPLETED,
            EventKind.CONFIRMATION,
            EventKind.INSTRUCTION_SKIPPED,
            EventKind.COMMAND_SENT,
            EventKind.RETRY,
        ):
            px, py = x(event.time), y + 2
            parts.append(
                f'<path d="M{px - 4:.1f},{py:.1f} L{px + 4:.1f},{py:.1f} L{px:.1f},{py + 7:.1f} Z" fill="#f39c12">'
                f"<title>{html.escape(event.actor)}: {html.escape(describe_event(event, wording))}</title></path>"
            )
    parts.append(f'<text x="{left}" y="14" fill="#555">bars: time in step · ▼ operator action · ● failure</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def _copy_images(summary: RunSummary, out_dir: Path) -> None:
    folder = out_dir / f"{summary.run_id}-images"
    for n, image in enumerate(summary.images, start=1):
        source = Path(image.source)
        if source.is_file():
            folder.mkdir(parents=True, exist_ok=True)
            target = folder / f"{n:02d}-{source.name}"
            shutil.copyfile(source, target)
            image.copied = f"{folder.name}/{target.name}"


def _reading(event: Event, wording: Wording) -> tuple[str, str, str, str]:
    """A verified reading as the report's telemetry table shows it: item, value, condition, result."""
    d = event.data
    if not isinstance(d, ep.TelemetrySeen):
        raise TypeError(f"event {event.seq} is a {event.kind.value}, not a reading")
    label, value, condition = reading_words(d, wording)
    met = d.ok is not False and not d.stale
    return label, value, condition or "(branch)", "ok" if met else "not met"


def to_markdown(summary: RunSummary, wording: Wording | None = None) -> str:
    """The report in Markdown (``wording``: labels and units, and whether the calls as sent show)."""
    said = wording or Wording()
    lines = [
        f"# After-action report: {summary.title}",
        "",
        f"- Run: `{summary.run_id}`",
        f"- Procedure: `{summary.procedure}` version {summary.version}",
        *([f"- Ran: **{summary.released}**"] if summary.released else []),
        *([f"- Part of the procedure: {summary.section}"] if summary.section else []),
        f"- Started: {summary.started:%Y-%m-%d %H:%M:%S} UTC by {summary.started_by}",
        f"- Duration: {_duration(summary.seconds)}",
        f"- Outcome: **{summary.outcome}**",
        *([f"- Audit chain: {summary.integrity}"] if summary.integrity else []),
        "",
        "## Steps",
        "",
        "| step | title | time | completed | failed | skipped | by |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in summary.steps:
        by = ", ".join(sorted(s.actors)) or "—"
        when = _duration(s.seconds) if s.visits else "not reached"
        lines.append(f"| {s.number} | {s.title} | {when} | {s.completed} | {s.failed} | {s.skipped} | {by} |")
    if summary.monitors:
        lines += ["", "## Monitors", "", *(f"- {said_of}" for said_of in summary.monitors)]
    lines += [
        "",
        "## Timeline",
        "",
        f"![timeline]({summary.run_id}-timeline.svg)",
        "",
        "## Verified telemetry",
        "",
        "| time | instruction | item | value | condition | result |",
        "|---|---|---|---|---|---|",
    ]
    for e in summary.telemetry:
        item, value, condition, verdict = _reading(e, said)
        lines.append(f"| {_clock(e.time)} | {e.instruction} | {item} | `{value}` | {condition} | {verdict} |")
    lines += ["", "## Images", ""]
    for image in summary.images:
        target = image.copied or image.source
        lines.append(
            f"- {image.instruction} at {_clock(image.time)} {image.label}: "
            + (f"![{image.label}]({target})" if image.copied else f"missing file {image.source}")
        )
    if not summary.images:
        lines.append("None captured.")
    lines += ["", "## Actions", "", "| # | time (UTC) | actor | instruction | action |", "|---|---|---|---|---|"]
    for e in summary.events:
        lines.append(
            f"| {e.seq} | {_clock(e.time)} | {e.actor} | {e.instruction or ''} "
            f"| {describe_event(e, said).replace('|', '/')} |"
        )
    return "\n".join(lines) + "\n"


def to_html(summary: RunSummary, wording: Wording | None = None) -> str:
    """The report as one HTML page (``wording`` as for :func:`to_markdown`)."""
    said = wording or Wording()
    esc = html.escape
    rows = "".join(
        f"<tr><td>{s.number}</td><td>{esc(s.title)}</td><td>{_duration(s.seconds) if s.visits else 'not reached'}</td>"
        f"<td>{s.completed}</td><td>{s.failed}</td><td>{s.skipped}</td><td>{esc(', '.join(sorted(s.actors)))}</td></tr>"
        for s in summary.steps
    )
    readings = [(e, *_reading(e, said)) for e in summary.telemetry]
    telemetry = "".join(
        f"<tr><td>{_clock(e.time)}</td><td>{esc(e.instruction or '')}</td><td>{esc(item)}</td>"
        f"<td><code>{esc(value)}</code></td><td>{esc(condition)}</td>"
        f"<td>{'ok' if verdict == 'ok' else '<b>not met</b>'}</td></tr>"
        for e, item, value, condition, verdict in readings
    )
    images = (
        "".join(
            f'<figure><img src="{esc(i.copied)}" alt="{esc(i.label)}" style="max-width:320px">'
            f"<figcaption>{esc(i.instruction)} {_clock(i.time)} {esc(i.label)}</figcaption></figure>"
            if i.copied
            else f"<p>{esc(i.instruction)}: missing file {esc(i.source)}</p>"
            for i in summary.images
        )
        or "<p>None captured.</p>"
    )
    actions = "".join(
        f'<tr class="{"operator" if e.actor != PAX else ""}"><td>{e.seq}</td><td>{_clock(e.time)}</td>'
        f"<td>{esc(e.actor)}</td>"
        f"<td>{esc(e.instruction or '')}</td><td>{esc(describe_event(e, said))}</td></tr>"
        for e in summary.events
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Run {esc(summary.run_id)}</title>
<style>
body{{font-family:sans-serif;margin:2em;max-width:1000px}} table{{border-collapse:collapse;margin:1em 0}}
td,th{{border:1px solid #ccc;padding:3px 8px;text-align:left;font-size:14px}} tr.operator td{{background:#fdf2e3}}
figure{{display:inline-block;margin:0 1em 1em 0}}
</style></head><body>
<h1>After-action report: {esc(summary.title)}</h1>
<p>Run <code>{esc(summary.run_id)}</code> · procedure <code>{esc(summary.procedure)}</code> v{esc(summary.version)} ·
started {summary.started:%Y-%m-%d %H:%M:%S} UTC by {esc(summary.started_by)} · {_duration(summary.seconds)} ·
outcome <b>{esc(summary.outcome)}</b></p>
{f"<p>Ran: <b>{esc(summary.released)}</b></p>" if summary.released else ""}
{f"<p>Part of the procedure: {esc(summary.section)}</p>" if summary.section else ""}
{f"<p>Audit chain: {esc(summary.integrity)}</p>" if summary.integrity else ""}
{_monitors_html(summary)}<h2>Steps</h2>
<table><tr><th>step</th><th>title</th><th>time</th><th>completed</th><th>failed</th><th>skipped</th><th>by</th></tr>{rows}</table>
<h2>Timeline</h2>
{timeline_svg(summary, wording=said)}
<h2>Verified telemetry</h2>
<table><tr><th>time</th><th>instruction</th><th>item</th><th>value</th><th>condition</th><th>result</th></tr>{telemetry}</table>
<h2>Images</h2>
{images}
<h2>Actions</h2>
<table><tr><th>#</th><th>time (UTC)</th><th>actor</th><th>instruction</th><th>action</th></tr>{actions}</table>
</body></html>
"""


def write_report(
    events: list[Event], out_dir: Path, *, integrity: str = "", wording: Wording | None = None
) -> tuple[Path, Path]:
    """Write ``RUN.html``, ``RUN.md`` and ``RUN-timeline.svg`` (and copied images) into ``out_dir``.

    ``integrity`` is what checking the run's hash chain found; the report states it. ``wording``:
    the SysReps whose labels and units it uses, and whether the calls as sent show (raw).
    """
    summary = summarize(events)
    summary.integrity = integrity
    out_dir.mkdir(parents=True, exist_ok=True)
    _copy_images(summary, out_dir)
    html_path = out_dir / f"{summary.run_id}.html"
    md_path = out_dir / f"{summary.run_id}.md"
    html_path.write_text(to_html(summary, wording), encoding="utf-8")
    md_path.write_text(to_markdown(summary, wording), encoding="utf-8")
    (out_dir / f"{summary.run_id}-timeline.svg").write_text(timeline_svg(summary, wording=wording), encoding="utf-8")
    return html_path, md_path


def _monitors_html(summary: RunSummary) -> str:
    """The monitors' section of the HTML report (empty when no monitor was violated)."""
    if not summary.monitors:
        return ""
    return "<h2>Monitors</h2><ul>" + "".join(f"<li>{html.escape(said)}</li>" for said in summary.monitors) + "</ul>\n"
