"""Random hostile input (hypothesis): mutated rosbridge messages, raw WebSocket frames and
rosbridge fragments.  Every request that must be answered is answered, a connection is closed
only for a WebSocket protocol error (with its code), and the ``watch`` fixture checks latency,
RSS and tracebacks (conftest.py).  bench/bridge_fuzz.py runs the same generators for 100,000+
inputs and reports the figures in docs/rosbridge.md.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from support.processes import ManagedProcess

from .hostile import BridgeLog, Watch, await_answers, hostile_frame, hostile_message, parses, serve_raw_frames
from .rosbridge_support import RawClient

pytestmark = [
    pytest.mark.slow(seconds=80),
    # Hypothesis warns when the global `random` changes while it draws an example; in this process
    # the fixtures' background threads (process readers, socket clients) may use it meanwhile, which
    # says nothing about the strategies (they draw from Hypothesis only). Seen once under heavy load.
    pytest.mark.filterwarnings("ignore:Do not use the `random` module inside strategies"),
]

FUZZ = settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
_ids = itertools.count()


@pytest.fixture(scope="module")
def fuzz_client(hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]]) -> Iterator[RawClient]:
    client = RawClient(*hostile_bridge[2], max_size=None)
    client.send({"op": "set_level", "level": "error"})
    yield client
    client.close()


@FUZZ
@given(rng=st.randoms(use_true_random=False), count=st.integers(1, 8))
def test_mutated_messages_are_all_answered(
    watch: Watch, fuzz_client: RawClient, rng: random.Random, count: int
) -> None:
    wanted: set[str] = set()
    for _ in range(count):
        if rng.random() < 0.4:
            request_id = f"fuzz {next(_ids)}"
            message = hostile_message(rng, request_id)
            if parses(message):  # else not even its id can be known: answered by status only
                wanted.add(request_id)
            fuzz_client.send(message)
        else:
            fuzz_client.send(hostile_message(rng))
    request_id = f"fuzz {next(_ids)}"
    fuzz_client.send({"op": "call_service", "service": "/rosapi/get_ros_version", "id": request_id})
    assert not await_answers(fuzz_client, wanted | {request_id})


@FUZZ
@given(rng=st.randoms(use_true_random=False), count=st.integers(1, 8))
def test_raw_frames_are_served_or_refused_with_their_close_code(
    watch: Watch, hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]], rng: random.Random, count: int
) -> None:
    frames = [hostile_frame(rng) for _ in range(count)]
    assert serve_raw_frames(hostile_bridge[2], frames), frames


FRAGMENT = st.fixed_dictionaries(
    {
        "op": st.just("fragment"),
        "id": st.sampled_from(["a", "b", 7, "c" * 200]),
        "num": st.one_of(st.integers(-2, 5), st.integers(2**31, 2**70)),
        "total": st.one_of(st.integers(-1, 6), st.integers(2**31, 2**70)),
        "data": st.one_of(
            st.text(max_size=40),
            st.just('{"op":"call_service","service":"/rosapi/get_time","id":"frag"}'),
            st.integers(1, 400_000).map(lambda n: "x" * n),
        ),
    }
)


@FUZZ
@given(fragments=st.lists(FRAGMENT, min_size=1, max_size=8))
def test_fragments_in_any_order_and_size_leave_the_connection_served(
    watch: Watch, fuzz_client: RawClient, fragments: list[dict]
) -> None:
    for fragment in fragments:
        fuzz_client.send(fragment)
    request_id = f"fuzz {next(_ids)}"
    fuzz_client.send({"op": "call_service", "service": "/rosapi/get_ros_version", "id": request_id})
    assert not await_answers(fuzz_client, {request_id})
