"""The reference agent follows an accepted run and says, once each time, what the run waits for.

A demo whose operator only accepts proposals reads those lines to stop at once instead of waiting
its whole time for an answer nobody gives; an operator reading the agent's output learns the same.
The MCP client is a double here: what the server answers is :mod:`agent.mcp_server`'s, tested in
tests/agents/test_agent_mcp.py.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import Any

import pytest

from agent.reference_agent import AgentStopped, ReferenceAgent


@dataclass
class Answer:
    structured_content: dict[str, Any] | None
    is_error: bool = False
    content: tuple[()] = ()


class ExplainedRuns:
    """An MCP client whose ``explain_run`` answers are given in order (the last repeats)."""

    def __init__(self, *answers: dict[str, Any]) -> None:
        self.answers = list(answers)

    async def call_tool(self, tool: str, arguments: dict[str, Any]) -> Answer:
        assert tool == "explain_run" and arguments == {"run_id": "r-1"}
        told = self.answers.pop(0) if len(self.answers) > 1 else self.answers[0]
        return Answer({"started_by": "alice", "started": "T0", "words": f"run r-1: {told['outcome']}", **told})


def timeline(capsys: pytest.CaptureFixture[str]) -> list[tuple[str, str]]:
    lines = [line.split(" ", 3) for line in capsys.readouterr().out.splitlines()]
    return [(event, words) for _, event, _, words in lines]


def test_each_new_wait_for_an_operator_is_said_once_and_the_completion_after_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    running = {"outcome": "running", "waiting_for": ""}
    held = {"outcome": "running", "waiting_for": "hold: the link is lost"}
    asked = {"outcome": "running", "waiting_for": "record: the filter's id"}
    client = ExplainedRuns(running, held, held, running, asked, {"outcome": "completed", "waiting_for": ""})
    asyncio.run(ReferenceAgent(client, "iva", every=0.0)._run_ended("r-1"))  # type: ignore[arg-type]
    assert timeline(capsys) == [
        ("start", "run r-1 started by alice at T0"),
        ("waiting", "run r-1 waits for an operator: hold: the link is lost"),
        ("waiting", "run r-1 waits for an operator: record: the filter's id"),
        ("completion", "run r-1: completed"),
    ]


def test_a_run_that_ends_otherwise_stops_the_agent_with_its_words(capsys: pytest.CaptureFixture[str]) -> None:
    client = ExplainedRuns({"outcome": "stopped", "waiting_for": ""})
    with pytest.raises(AgentStopped, match="run r-1 stopped: run r-1: stopped"):
        asyncio.run(ReferenceAgent(client, "iva", every=0.0)._run_ended("r-1"))  # type: ignore[arg-type]
    assert timeline(capsys) == [("start", "run r-1 started by alice at T0")]
