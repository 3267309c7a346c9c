"""Send one signed unit to the habitat's onboard executive, as anyone on the link could, and again.

Runs in the ground's network namespace: ``unit_sender.py BINDING UNIT_FILE``. ``UNIT_FILE`` holds
``{"unit_json": ..., "signature": ...}``, sent byte for byte as it is each time. It connects through
the binding's rosbridge (wss, the link's secret), prints ``READY sender``, then on each SIGUSR1
sends the unit and prints ``ANSWER <json>`` (the habitat's answer), and on SIGUSR2 asks the
habitat's status and prints ``STATUS <json>``. SIGTERM ends it.
"""

from __future__ import annotations

import asyncio
import json
import signal
import sys
from pathlib import Path

from onboard.unit import STATUS_SERVICE, UPLINK_SERVICE
from procedure_language.binding import read_binding
from rosbridge_wire.client import RosbridgeClient


async def main(binding: str, unit_file: str) -> None:
    request = json.loads(Path(unit_file).read_text(encoding="utf-8"))
    client = RosbridgeClient(read_binding(binding).endpoint(), name="unit-sender")
    client.start()
    await client.ready.wait()
    loop = asyncio.get_running_loop()
    asks: asyncio.Queue[signal.Signals] = asyncio.Queue()
    for signum in (signal.SIGUSR1, signal.SIGUSR2, signal.SIGTERM):
        loop.add_signal_handler(signum, asks.put_nowait, signum)
    print("READY sender", flush=True)
    try:
        while (ask := await asks.get()) is not signal.SIGTERM:
            if ask is signal.SIGUSR1:
                answer = await client.call(UPLINK_SERVICE, request, timeout=client.call_timeout(60.0))
                print(f"ANSWER {json.dumps(dict(answer), sort_keys=True)}", flush=True)
            else:
                status = await client.call(STATUS_SERVICE, {}, timeout=client.call_timeout(60.0))
                print(f"STATUS {json.dumps(dict(status), sort_keys=True)}", flush=True)
    finally:
        await client.close()


if __name__ == "__main__":
    asyncio.run(main(*sys.argv[1:3]))
