"""The live page's HTTP face on a plain (not living) served machine: files, status, events, errors."""

from __future__ import annotations

import asyncio
import json
import urllib.error
import urllib.request

from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.faces.web import WebFace
from nckemu.emulator.machine.core import Emulator


def _get(port: int, path: str, method: str = "GET") -> tuple[int, bytes]:
    request = urllib.request.Request(f"http://127.0.0.1:{port}{path}", method=method)
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, answer.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


async def _raw(port: int, data: bytes) -> bytes:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(data)
    answer = await reader.read(4096)
    writer.close()
    return answer


async def test_plain_machine_page() -> None:
    emulator = Emulator()
    server = EmulatorServer(emulator, port=0)
    await server.start()
    face = WebFace(emulator, server, port=0, sample_period_s=0.1)
    await face.start()
    try:
        async with AsyncNckClient("127.0.0.1", server.port) as client:
            await client.put({"SD43900[AX4]": 0.25})
            for _ in range(5):
                await client.get("SD43900[AX4]")
            await asyncio.sleep(0.4)
            status, body = await asyncio.to_thread(_get, face.port, "/status.json")
            document = json.loads(body)
            assert status == 200 and "live" not in document
            z = next(a for a in document["axes"] if a["name"] == "Z1")
            assert z["sd43900_mm"] == 0.25 and z["md32750"] is not None
            assert document["clients"][0]["jobs"] >= 6 and document["speed"] == 1.0
            assert (await asyncio.to_thread(_get, face.port, "/"))[0] == 200
            assert (await asyncio.to_thread(_get, face.port, "/", "HEAD"))[0] == 200
            assert (await asyncio.to_thread(_get, face.port, "/etc/passwd"))[0] == 404
            assert (await asyncio.to_thread(_get, face.port, "/", "POST"))[0] == 405
            assert (await _raw(face.port, b"NONSENSE\r\n\r\n")).startswith(b"HTTP/1.1 400")
            assert len(face.history) >= 3
            events = await _raw(face.port, b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
            assert b"text/event-stream" in events and b"event: history" in events
            # the S7 face serves on meanwhile
            assert (await client.get("SD43900[AX4]"))[0] == 0.25
    finally:
        await face.stop()
        await server.stop()
