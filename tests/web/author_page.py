"""What the browser tests do on the Author page: find cards, drag, fill arguments and attributes."""

from __future__ import annotations

from playwright.sync_api import Locator, Page, expect


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
    page.drag_and_drop(palette_item, drop_zone(step, index))
    expect(items).to_have_count(before + 1)


def set_arg(page: Page, number: str, name: str, value: str) -> None:
    field = card(page, number).locator(f'.arg[data-arg="{name}"] .arg-value')
    field.fill(value)
    field.press("Tab")


def bind_arg(page: Page, number: str, name: str, variable: str) -> None:
    card(page, number).locator(f'.arg[data-arg="{name}"] .arg-bind').select_option(variable)


def set_attr(page: Page, number: str, name: str, value: str) -> None:
    field = card(page, number).locator(f'[data-attr="{name}"]')
    field.fill(value)
    field.press("Tab")
