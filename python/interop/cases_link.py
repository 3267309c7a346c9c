"""The ``link`` profile: the ``core`` and ``services`` cases again, across a long, lossy link with
outages, and a client that goes quiet and comes back.

The suite cannot make the link: the user puts one between it and the server (``caretaker link``,
a satellite modem) and states its one-way delay and longest outage (``--link-delay``,
``--outage``), which grow every wait of every case. What the ``link`` profile adds is what a link
does to a server: a client that reads nothing for a while (``--quiet``, 30 s by default), whose
kernel buffers fill while the server keeps writing to it, and that then reads again.
"""

from __future__ import annotations

import asyncio
import dataclasses
from collections.abc import Iterable

from .outcome import Outcome
from .runner import Case, CaseContext, Verdict
from .session import op_is
from .steps import STRING, call_served, new_id, publish_until, topic_pair

__all__ = ["again_over_the_link", "quiet_case"]

SET_BOOL = "std_srvs/srv/SetBool"


def again_over_the_link(cases: Iterable[Case]) -> tuple[Case, ...]:
    """The cases again as ``link.<number>``: same checks, the link's statement cited too."""
    return tuple(
        dataclasses.replace(
            case, number=f"link.{case.number}", profile="link", statements=(*case.statements, "P-LINK-3")
        )
        for case in cases
    )


async def quiet_and_back(context: CaseContext) -> Verdict:
    quiet, other = await context.connect_pair("quiet", "other")
    topic, service = context.name("feed"), context.name("served")
    await topic_pair(other, quiet, topic, STRING)
    await quiet.send({"op": "advertise_service", "id": new_id("adv"), "service": service, "type": SET_BOOL})
    await publish_until(other, quiet, topic, {"data": "before"}, 15)
    call = {"op": "call_service", "service": service, "args": {"data": True}, "timeout": 5.0}
    await call_served(quiet, other, call, {"success": True, "message": "before"}, 20)

    seconds = context.target.quiet
    silence = asyncio.ensure_future(quiet.socket.go_quiet(seconds))
    # Meanwhile the other client publishes, calls the quiet client's service and its own probe.
    call_id = new_id("during")
    await other.send({**call, "id": call_id})
    published = 0
    while not silence.done():
        await other.send({"op": "publish", "topic": topic, "msg": {"data": f"during-{published}"}})
        published += 1
        await asyncio.sleep(0.5)  # 2 Hz, the status topic's rate
    answer = await other.expect(op_is("service_response", id=call_id), 15, "the answer to a call of the quiet client")
    if answer.get("result") is not False:
        return Verdict(Outcome.FAILED, f"a call of the quiet client's service was answered {answer}")
    if not await other.still_serves(15):
        return Verdict(Outcome.FAILED, "the other client was not served while one client was quiet")
    await silence

    if quiet.closed is not None:
        return Verdict(
            Outcome.INFORMATIONAL,
            f"the server closed the client quiet for {seconds:g} s (code {quiet.closed.code}); others were served",
        )
    quiet.discard(op_is("call_service", service=service))  # the call made while it was quiet
    await publish_until(other, quiet, topic, {"data": "back"}, 30, lambda m: m.get("msg") == {"data": "back"})
    await call_served(quiet, other, call, {"success": True, "message": "back"}, 30)
    during = sum(1 for m in quiet.received if str(m.get("msg", {}).get("data", "")).startswith("during-"))
    return Verdict(
        Outcome.OK,
        f"after {seconds:g} s quiet the client's subscription and service work again ({during} of {published} "
        "messages published meanwhile reached it); the others were served meanwhile, its service's call "
        "answered result false",
    )


def quiet_case() -> Case:
    return Case(
        "link.quiet",
        "a client that goes quiet and comes back",
        "link",
        ("P-LINK-1", "P-LINK-2", "P-SRV-5"),
        "others served while one client reads nothing; its subscription and service work again after",
        180,  # --quiet is at most 60 s
        quiet_and_back,
    )
