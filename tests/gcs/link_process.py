"""A GroundLink in a process of its own (accepts every command), for the tests that kill it: prints
``connected`` once it is up. ``python -m tests.gcs.link_process BROKER_URL VEHICLE_ID [REJECT_REASON]``."""

from __future__ import annotations

import asyncio
import sys

from app.gcs.config import GcsSettings
from app.gcs.link import GroundLink


async def main(url: str, vehicle_id: str, reason: str | None) -> None:
    link = GroundLink(GcsSettings.from_mapping({"broker_url": url, "vehicle_id": vehicle_id}), lambda _: reason)
    task = asyncio.create_task(link.run())
    await link.wait_connected()
    print("connected", flush=True)
    await task


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None))
