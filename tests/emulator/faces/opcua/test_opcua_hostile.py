"""Hostile input on the OPC UA face: each fault bench/fuzz_opcua.py found in asyncua's handling, as the
smallest message that showed it (docs/asyncua-hostile-input.md), and the fuzz run itself at its small
size. The face answers with OPC UA's errors or closes that connection; other clients go on."""

from __future__ import annotations

import asyncio
import logging
import struct
from collections.abc import Iterator
from typing import Any

import pytest
from asyncua import ua

from bench.opcua_wire import Answer, Wire
from nckemu.emulator.faces.opcua import OpcUaFace, asyncua_internals
from nckemu.emulator.faces.opcua.transport import Limits
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import two_faces

pytestmark = pytest.mark.timeout(180)
HOST = "127.0.0.1"
# What the face leaves to asyncua 2.x (pyproject asks for it); an older asyncua still imports and serves
# without it (asyncua_internals.MENDED_IN_2), and these tests of it skip there, saying why.
mended_in_asyncua_2 = pytest.mark.skipif(
    bool(asyncua_internals.MENDED_IN_2),
    reason=f"asyncua {asyncua_internals.VERSION} lacks {' and '.join(asyncua_internals.MENDED_IN_2)} (asyncua 2.x)")


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        # a short partial timeout for the tests (the face's own is 10 s)
        pair[1].server.iserver.nckemu_transport_limits = Limits(partial_timeout_s=0.5)
        yield pair


def on_loop(pair: tuple[EmulatorThread, OpcUaFace], coroutine: Any) -> Any:
    """Run a client coroutine on a loop of its own (the faces serve on theirs)."""
    return asyncio.run(coroutine)


async def session(face: OpcUaFace, user: str | None = None, password: str | None = None) -> Wire:
    wire = Wire(face.url)
    got = await wire.handshake(HOST, face.port, user, password)
    assert got.good, got
    return wire


async def still_served(face: OpcUaFace) -> bool:
    wire = await session(face)
    try:
        return (await wire.ask(wire.read())).good
    finally:
        wire.close()


def status(got: Answer) -> str:
    return ua.StatusCode(got.status).name


def test_a_request_that_does_not_decode_gets_bad_decoding_error_and_no_traceback(
        faces: tuple[EmulatorThread, OpcUaFace], caplog: pytest.LogCaptureFixture) -> None:
    async def go() -> tuple[Answer, Answer]:
        wire = await session(faces[1])
        data = bytearray(wire.read())
        data[-10:-6] = struct.pack("<i", 0x7FFFFFFF)  # the IndexRange string's length: far past the end
        wire.send(bytes(data))
        first = await wire.until(wire.request_id, 5)
        second = await wire.ask(wire.read())  # the session goes on
        wire.close()
        return first, second

    with caplog.at_level(logging.WARNING):
        first, second = on_loop(faces, go())
    assert first.kind == "MSG" and status(first) == "BadDecodingError"
    assert second.good
    assert "Traceback" not in caplog.text and not [r for r in caplog.records if r.levelno >= logging.ERROR]


def test_a_wrong_sequence_number_is_an_error_message_and_closes(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> tuple[Answer, Answer]:
        wire = await session(faces[1])
        data = bytearray(wire.read())
        data[16:20] = struct.pack("<I", struct.unpack_from("<I", data, 16)[0] - 1)  # the one before again
        wire.send(bytes(data))
        return await wire.answer(5), await wire.answer(5)

    error, after = on_loop(faces, go())
    assert error.kind == "ERR" and ua.StatusCode(error.status).name == "BadSequenceNumberInvalid"
    assert after.kind == "closed"
    assert on_loop(faces, still_served(faces[1]))


@pytest.mark.parametrize("chunk", [b"A", b"C", b"X"])
def test_an_open_secure_channel_that_is_not_a_final_chunk_is_an_error_and_closes(
        faces: tuple[EmulatorThread, OpcUaFace], chunk: bytes) -> None:
    """OPN with chunk type A (found by the fuzz run: asyncua said nothing and kept the connection)."""
    async def go() -> tuple[Answer, Answer]:
        wire = Wire(faces[1].url)
        await wire.connect(HOST, faces[1].port)
        wire.send(wire.hello())
        await wire.answer(5)
        data = bytearray(wire.open())
        data[3:4] = chunk
        wire.send(bytes(data))
        return await wire.answer(5), await wire.answer(5)

    error, after = on_loop(faces, go())
    assert error.kind == "ERR" and status(error) == "BadTcpMessageTypeInvalid"
    assert after.kind == "closed"


def test_a_size_past_the_receive_buffer_is_refused_from_the_header(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> tuple[Answer, Answer]:
        wire = await session(faces[1])
        wire.send(b"MSGF" + struct.pack("<I", 0xFFFFFFF0) + bytes(4))  # 4 GiB promised: asyncua buffered it
        return await wire.answer(5), await wire.answer(5)

    error, after = on_loop(faces, go())
    assert error.kind == "ERR" and ua.StatusCode(error.status).name == "BadTcpMessageTooLarge"
    assert after.kind == "closed"


@pytest.mark.parametrize("sent", [b"", b"HEL", b"HELF\x40\x00\x00\x00\x00"], ids=["nothing", "3 bytes", "a header"])
def test_a_half_open_connection_is_closed_after_the_partial_timeout(
        faces: tuple[EmulatorThread, OpcUaFace], sent: bytes) -> None:
    async def go() -> tuple[Answer, float]:
        wire = Wire(faces[1].url)
        await wire.connect(HOST, faces[1].port)
        wire.send(sent)
        started = asyncio.get_running_loop().time()
        first = await wire.answer(10)
        rest = await wire.answer(5) if first.kind == "ERR" else first
        return rest, asyncio.get_running_loop().time() - started

    after, waited = on_loop(faces, go())
    assert after.kind == "closed" and waited < 5


def test_chunks_that_never_end_are_closed_after_the_partial_timeout(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> list[str]:
        wire = await session(faces[1])
        chunk = bytearray(wire.read())
        chunk[3:4] = b"C"  # an intermediate chunk: asyncua waits for the final one forever
        wire.send(bytes(chunk))
        return [(await wire.answer(10)).kind, (await wire.answer(5)).kind]

    assert on_loop(faces, go()) == ["ERR", "closed"]


def test_the_first_message_must_be_a_hello(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> Answer:
        wire = Wire(faces[1].url)
        await wire.connect(HOST, faces[1].port)
        wire.send(wire.open())
        return await wire.answer(5)

    got = on_loop(faces, go())
    assert got.kind == "ERR" and ua.StatusCode(got.status).name == "BadTcpMessageTypeInvalid"


def test_an_open_secure_channel_with_a_garbage_certificate_is_refused(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> tuple[Answer, Answer]:
        wire = Wire(faces[1].url)
        await wire.connect(HOST, faces[1].port)
        wire.send(wire.hello())
        await wire.answer(5)
        wire.send(wire.open("http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256", b"\x30\x82garbage",
                            ua.MessageSecurityMode.SignAndEncrypt))
        return await wire.answer(5), await wire.answer(5)

    error, after = on_loop(faces, go())
    assert error.kind == "ERR" and after.kind == "closed"


def test_a_second_create_session_on_a_channel_closes_the_first(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    face = faces[1]

    def open_sessions() -> int:
        return sum(1 for s in face.sessions.made if s.state.name != "Closed")

    async def go() -> int:
        before = open_sessions()
        wire = Wire(face.url)
        await wire.connect(HOST, face.port)
        wire.send(wire.hello())
        await wire.answer(5)
        await wire.ask(wire.open())
        for _ in range(50):
            assert (await wire.ask(wire.create_session())).good
        grown = open_sessions() - before
        wire.close()
        return grown

    assert on_loop(faces, go()) <= 1


def test_requests_sent_faster_than_served_wait_and_are_all_answered(
        faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """A client that sends requests without reading the answers: past the messages asyncua 2.x queues for a
    connection (500; it then closes the connection in silence) the face stops reading until it has served
    them, and every request is answered."""
    async def go() -> list[str]:
        wire = await session(faces[1])
        wire.send(b"".join(wire.read() for _ in range(2000)))
        seen = [(await wire.answer(10)).kind for _ in range(2000)]
        wire.close()
        return seen

    seen = on_loop(faces, go())
    assert seen.count("MSG") == 2000, {kind: seen.count(kind) for kind in set(seen)}


@mended_in_asyncua_2
def test_publish_requests_past_the_cap_are_refused(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """asyncua 2.x keeps a channel's subscriptions + 10 Publish requests and refuses the oldest past that."""
    async def go() -> dict[str, int]:
        wire = await session(faces[1], "nckemu", "SUNRISE")
        await wire.subscribe()
        wire.send(b"".join(wire.publish() for _ in range(120)))
        seen: dict[str, int] = {}
        for _ in range(20):
            got = await wire.answer(5)
            seen[status(got)] = seen.get(status(got), 0) + 1
        wire.close()
        return seen

    assert on_loop(faces, go()).get("BadTooManyPublishRequests", 0) >= 19


def test_too_many_operations_in_one_request_are_refused_before_decoding(
        faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> tuple[str, str]:
        wire = await session(faces[1])
        many = await wire.ask(wire.read(*[ua.NodeId("/Channel/State/progStatus", 2)] * 1001))
        few = await wire.ask(wire.read(*[ua.NodeId("/Channel/State/progStatus", 2)] * 1000))
        wire.close()
        return status(many), status(few)

    assert on_loop(faces, go()) == ("BadTooManyOperations", "Good")


def test_a_user_name_token_without_a_name_is_no_anonymous_login(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> list[str]:
        results = []
        for user, password in (("", "SUNRISE"), ("", ""), ("nckemu", "")):
            wire = Wire(faces[1].url)
            results.append(status(await wire.handshake(HOST, faces[1].port, user, password)))
            wire.close()
        return results

    assert on_loop(faces, go()) == ["BadUserAccessDenied"] * 3


def test_a_method_called_with_too_few_or_too_many_arguments_is_refused_without_a_traceback(
        faces: tuple[EmulatorThread, OpcUaFace], caplog: pytest.LogCaptureFixture) -> None:
    """A CallMethodRequest with no arguments to CopyFileToServer (found by the fuzz run: asyncua called the
    handler anyway and logged the TypeError with a traceback)."""
    from bench.opcua_wire import COPY_TO, GET_RIGHTS, METHODS

    def call(wire: Wire, method: ua.NodeId, arguments: list[ua.Variant]) -> bytes:
        request = ua.CallRequest()
        request.Parameters = ua.CallParameters(MethodsToCall=[ua.CallMethodRequest(
            ObjectId=METHODS, MethodId=method, InputArguments=arguments)])
        return wire.secure(request)

    async def go() -> list[str]:
        wire = await session(faces[1], "nckemu", "SUNRISE")
        names = []
        for method, arguments in ((COPY_TO, []), (COPY_TO, [ua.Variant("x")]), (GET_RIGHTS, [ua.Variant(1)]),
                                  (GET_RIGHTS, [])):
            got = await wire.ask(call(wire, method, arguments))
            names.append(got.decode(ua.CallResponse).Results[0].StatusCode.name)
        wire.close()
        return names

    with caplog.at_level(logging.WARNING):
        names = on_loop(faces, go())
    assert names == ["BadArgumentsMissing", "BadArgumentsMissing", "BadTooManyArguments", "Good"]
    assert "Traceback" not in caplog.text and not [r for r in caplog.records if r.levelno >= logging.ERROR]


@mended_in_asyncua_2
def test_a_session_that_times_out_is_closed_without_a_traceback(
        faces: tuple[EmulatorThread, OpcUaFace], caplog: pytest.LogCaptureFixture) -> None:
    """asyncua's watchdog closed a timed-out session by waiting on itself; the connection's close then
    raised that again ("Unexpected crash in BinaryServer._close_tasks", found by the fuzz run)."""
    async def go() -> tuple[str, Answer]:
        wire = Wire(faces[1].url)
        await wire.connect(HOST, faces[1].port)
        wire.send(wire.hello())
        await wire.answer(5)
        await wire.ask(wire.open())
        created = await wire.ask(wire.create_session(timeout_ms=1000.0))
        wire.token = created.decode(ua.CreateSessionResponse).Parameters.AuthenticationToken
        activated = await wire.ask(wire.activate())
        await asyncio.sleep(2.5)  # idle past the timeout: the watchdog closes the session
        after = await wire.ask(wire.read())
        wire.close()
        await asyncio.sleep(0.5)
        return status(activated), after

    binary_server = faces[1].server.bserver
    with caplog.at_level(logging.WARNING):
        activated, after = on_loop(faces, go())
        closing = list(binary_server.closing_tasks)
    assert activated == "Good"
    assert after.kind == "MSG" and status(after) in ("BadSessionClosed", "BadSessionIdInvalid", "BadSessionNotActivated")
    failed = [task for task in closing if task.done() and not task.cancelled() and task.exception()]
    assert not failed, [task.exception() for task in failed]
    assert "Traceback" not in caplog.text and not [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert on_loop(faces, still_served(faces[1]))


# ~50 s of one core: a search, not a check; each fault it found has its smallest message as a test above,
# so the default suite keeps those and the slow suite (CI runs it too) the search.
@pytest.mark.slow
def test_the_fuzz_run_small(tmp_path: Any) -> None:
    """bench/fuzz_opcua.py at its small size: mutated messages of every type and the named attacks, a
    python-snap7 and an asyncua client served throughout, no crash, no traceback, no stuck connection."""
    from bench.fuzz_opcua import run, verdict

    result = run(cases=250, seconds=120, seed=3, workers=4, attack_scale=0.1)
    assert not verdict(result), (verdict(result), result)
    assert result["cases"] >= 250 and set(result["by_message"]) >= {
        "hello", "open", "create_session", "activate", "read", "write", "browse", "call", "monitor", "publish"}
