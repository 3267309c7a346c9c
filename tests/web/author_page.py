"""What the browser tests do on the Author page: find cards, drag, fill arguments and attributes;
and what a saved procedure means, to compare it with the file it was opened from."""

from __future__ import annotations

import dataclasses
from typing import Any

from playwright.sync_api import Locator, Page, expect

from procedure_language.model import Location, Procedure


def meaning(procedure: Procedure) -> Any:
    """Everything a run reads of ``procedure`` (steps, instructions, monitors, inputs, outputs, with
    every value) and nothing of where it is written (file, lines): equal for a file and its re-save."""

    def shape(value: Any) -> Any:
        if isinstance(value, Location):
            return None
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            fields = [f for f in dataclasses.fields(value) if f.compare and f.name != "path"]
            return type(value).__name__, {f.name: shape(getattr(value, f.name)) for f in fields}
        if isinstance(value, (tuple, list)):
            return [shape(v) for v in value]
        return value

    return shape(procedure)


def card(page: Page, number: str) -> Locator:
    """The canvas card numbered as the executive will number it (``1.3``)."""
    return page.locator(f'#canvas .card[data-number="{number}"]')


def drop_zone(step: int, index: int) -> str:
    """The place before item ``index`` of step ``step`` (both from 0)."""
    return f'#canvas .drop[data-step="{step}"][data-index="{index}"]'


def drop(page: Page, palette_item: str, index: int, step: int = 0) -> None:
    """Drag a palette item into ``step`` at ``index`` (the step has ``index`` items before it)."""
    expect(page.locator("#check-state")).not_to_have_text("checking…")  # the canvas is drawn
    items = page.locator(f'#canvas .canvas-step[data-step="{step}"] .card')
    before = items.count()
    # in view first: a page that scrolled to the zone while the mouse was down would drag whatever
    # palette item had moved under it
    page.locator(drop_zone(step, index)).scroll_into_view_if_needed()
    page.drag_and_drop(palette_item, drop_zone(step, index))
    expect(items).to_have_count(before + 1)


def set_arg(page: Page, number: str, name: str, value: str) -> None:
    field = card(page, number).locator(f'.arg[data-arg="{name}"] .arg-value')
    field.fill(value)
    field.press("Tab")


def bind_arg(page: Page, number: str, name: str, variable: str) -> None:
    card(page, number).locator(f'.arg[data-arg="{name}"] .arg-bind').select_option(variable)


def set_attr(page: Page, which: str | Locator, name: str, value: str) -> None:
    """Type ``value`` into attribute ``name`` of a card (its number, or a locator: a monitor has no number)."""
    field = _card(page, which).locator(f'[data-attr="{name}"]')
    field.fill(value)
    field.press("Tab")


def select_attr(page: Page, which: str | Locator, name: str, value: str) -> None:
    """Choose ``value`` for attribute ``name`` of a card (its number, or a locator)."""
    _card(page, which).locator(f'select[data-attr="{name}"]').select_option(value)


def _card(page: Page, which: str | Locator) -> Locator:
    return card(page, which) if isinstance(which, str) else which
