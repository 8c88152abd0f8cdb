"""A raw OPC UA TCP connection (security None) whose messages are built with asyncua's own binary
encoders, so that a fuzzer can send each message valid or mutated and read what comes back.

``Wire`` keeps what a real client keeps (channel id, token id, sequence numbers, request ids, the
session's authentication token) and builds the next message; ``Wire.send``/``Wire.answer`` do the I/O
on asyncio streams. Nothing here keeps the server honest: the caller decides what was expected.
"""

from __future__ import annotations

import asyncio
import struct
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from asyncua import ua
from asyncua.common.connection import SecureConnection, TransportLimits
from asyncua.common.utils import Buffer
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.ua.ua_binary import nodeid_from_binary, struct_from_binary, struct_to_binary, uatcp_to_binary

NS = 2  # SinumerikVarProvider
READ_NODE = ua.NodeId("/Channel/State/progStatus", NS)
WRITE_NODE = ua.NodeId("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", NS)
METHODS = ua.NodeId("/Methods", NS)
GET_RIGHTS = ua.NodeId("/Methods/GetMyAccessRights", NS)
COPY_TO = ua.NodeId("/Methods/CopyFileToServer", NS)


@dataclass
class Answer:
    """What came back: an OPC UA TCP error (``ERR``), a response (its type id and service result),
    ``closed`` (the server closed the connection) or ``silent`` (nothing in the time given)."""

    kind: str
    status: int = 0
    typeid: int = 0
    request_id: int = 0
    body: bytes = b""

    @property
    def good(self) -> bool:
        return self.kind == "MSG" and not self.status & 0x80000000

    def decode(self, cls: Any) -> Any:
        return struct_from_binary(cls, Buffer(self.body))


def _value_of(node: ua.NodeId) -> ua.ReadValueId:
    """The value attribute of ``node`` (by position: asyncua 1.1 named the field NodeId_, 2.x NodeId)."""
    return ua.ReadValueId(node, ua.AttributeIds.Value)


def _typeid(cls: Any) -> int:
    return int(cls().TypeId.Identifier)


class Wire:
    """One connection's client-side state; every ``build_*`` returns the bytes of one valid message."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.conn = SecureConnection(SecurityPolicyNone(), TransportLimits(65535, 65535, 0, 0))
        self.request_id = 0
        self.handle = 0
        self.token = ua.NodeId()
        self.subscription = 0
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None
        self.skipped = 0  # answers ``until`` passed over (to other request ids)

    # ---------------------------------------------------------------- building
    def hello(self) -> bytes:
        return uatcp_to_binary(ua.MessageType.Hello, ua.Hello(EndpointUrl=self.url))

    def secure(self, request: Any, kind: bytes = ua.MessageType.SecureMessage) -> bytes:
        self.handle += 1
        self.request_id += 1
        request.RequestHeader = ua.RequestHeader(AuthenticationToken=self.token, Timestamp=datetime.now(UTC),
                                                 RequestHandle=self.handle, TimeoutHint=10000)
        return self.conn.message_to_binary(struct_to_binary(request), message_type=kind, request_id=self.request_id)

    def open(self, policy: str = "http://opcfoundation.org/UA/SecurityPolicy#None", certificate: bytes | None = None,
             mode: int = ua.MessageSecurityMode.None_) -> bytes:
        request = ua.OpenSecureChannelRequest()
        request.Parameters = ua.OpenSecureChannelParameters(
            ClientProtocolVersion=0, RequestType=ua.SecurityTokenRequestType.Issue, SecurityMode=mode,
            ClientNonce=b"", RequestedLifetime=600_000)
        data = self.secure(request, ua.MessageType.SecureOpen)
        if policy != self.conn.security_policy.URI or certificate is not None:  # another asymmetric header
            header = struct_to_binary(ua.AsymmetricAlgorithmHeader(SecurityPolicyURI=policy,
                                                                    SenderCertificate=certificate))
            old = struct_to_binary(ua.AsymmetricAlgorithmHeader())
            assert data[12:12 + len(old)] == old
            data = data[:12] + header + data[12 + len(old):]
            data = data[:4] + struct.pack("<I", len(data)) + data[8:]
        return data

    def create_session(self, timeout_ms: float = 60_000.0) -> bytes:
        request = ua.CreateSessionRequest()
        client = ua.ApplicationDescription(ApplicationUri="urn:fuzz", ApplicationName=ua.LocalizedText("fuzz"))
        client.ApplicationType = ua.ApplicationType.Client  # set by name: asyncua 1.1's field was ApplicationType_
        request.Parameters = ua.CreateSessionParameters(
            ClientDescription=client, EndpointUrl=self.url, SessionName="fuzz", ClientNonce=b"\x00" * 32, RequestedSessionTimeout=timeout_ms,
            MaxResponseMessageSize=0)
        return self.secure(request)

    def activate(self, user: str | None = None, password: str | bytes | None = None) -> bytes:
        request = ua.ActivateSessionRequest()
        params = ua.ActivateSessionParameters()
        if user is None:
            params.UserIdentityToken = ua.AnonymousIdentityToken(PolicyId="anonymous")
        else:
            secret = password.encode() if isinstance(password, str) else password
            params.UserIdentityToken = ua.UserNameIdentityToken(PolicyId="username", UserName=user, Password=secret)
        params.LocaleIds = ["en"]
        request.Parameters = params
        return self.secure(request)

    def read(self, *nodes: ua.NodeId) -> bytes:
        request = ua.ReadRequest()
        request.Parameters = ua.ReadParameters(NodesToRead=[
            _value_of(node) for node in (nodes or (READ_NODE,))])
        return self.secure(request)

    def write(self, value: float = 1.5) -> bytes:
        request = ua.WriteRequest()
        request.Parameters = ua.WriteParameters(NodesToWrite=[ua.WriteValue(
            WRITE_NODE, ua.AttributeIds.Value, Value=ua.DataValue(ua.Variant(value, ua.VariantType.Double)))])
        return self.secure(request)

    def browse(self) -> bytes:
        request = ua.BrowseRequest()
        request.Parameters = ua.BrowseParameters(RequestedMaxReferencesPerNode=20, NodesToBrowse=[ua.BrowseDescription(
            ua.NodeId("/Channel", NS), ua.BrowseDirection.Forward, ReferenceTypeId=ua.NodeId(ua.ObjectIds.HierarchicalReferences), IncludeSubtypes=True, ResultMask=63)])
        return self.secure(request)

    def call(self, copy: bool = False) -> bytes:
        request = ua.CallRequest()
        if copy:
            arguments = [ua.Variant("Sinumerik/FileSystem/Part Program/FUZZ.MPF", ua.VariantType.String),
                         ua.Variant(b"G1 X1\nM30\n", ua.VariantType.ByteString), ua.Variant(True, ua.VariantType.Boolean)]
            method = ua.CallMethodRequest(ObjectId=METHODS, MethodId=COPY_TO, InputArguments=arguments)
        else:
            method = ua.CallMethodRequest(ObjectId=METHODS, MethodId=GET_RIGHTS, InputArguments=[])
        request.Parameters = ua.CallParameters(MethodsToCall=[method])
        return self.secure(request)

    def create_subscription(self) -> bytes:
        request = ua.CreateSubscriptionRequest()
        request.Parameters = ua.CreateSubscriptionParameters(
            RequestedPublishingInterval=100, RequestedLifetimeCount=600, RequestedMaxKeepAliveCount=20,
            MaxNotificationsPerPublish=1000, PublishingEnabled=True)
        return self.secure(request)

    def monitor(self, count: int = 1, node: ua.NodeId = READ_NODE) -> bytes:
        request = ua.CreateMonitoredItemsRequest()
        items = [ua.MonitoredItemCreateRequest(
            _value_of(node), ua.MonitoringMode.Reporting, RequestedParameters=ua.MonitoringParameters(ClientHandle=i + 1, SamplingInterval=100, QueueSize=1,
                                                        DiscardOldest=True)) for i in range(count)]
        request.Parameters = ua.CreateMonitoredItemsParameters(self.subscription, ua.TimestampsToReturn.Both,
                                                               ItemsToCreate=items)
        return self.secure(request)

    def publish(self) -> bytes:
        request = ua.PublishRequest()
        request.Parameters = ua.PublishParameters(SubscriptionAcknowledgements=[])
        return self.secure(request)

    def close_channel(self) -> bytes:
        return self.secure(ua.CloseSecureChannelRequest(), ua.MessageType.SecureClose)

    # ---------------------------------------------------------------- I/O
    async def connect(self, host: str, port: int) -> None:
        self.reader, self.writer = await asyncio.open_connection(host, port, limit=1 << 22)

    def send(self, data: bytes) -> None:
        assert self.writer is not None
        self.writer.write(data)

    async def answer(self, timeout_s: float) -> Answer:
        """The next complete message from the server (chunks joined)."""
        assert self.reader is not None
        parts: list[bytes] = []
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        try:
            while True:
                left = deadline - loop.time()
                if left <= 0:
                    return Answer("silent")
                head = await asyncio.wait_for(self.reader.readexactly(8), left)
                kind, chunk, size = struct.unpack("<3scI", head)
                if size < 8 or size > 1 << 24:
                    return Answer("garbled")
                rest = await asyncio.wait_for(self.reader.readexactly(size - 8), max(0.01, deadline - loop.time()))
                if kind == b"ERR":
                    return Answer("ERR", status=struct.unpack_from("<I", rest)[0])
                if kind == b"ACK":
                    return Answer("ACK")
                if kind == b"OPN":
                    data = Buffer(rest[4:])
                    struct_from_binary(ua.AsymmetricAlgorithmHeader, data)
                    sequence = struct_from_binary(ua.SequenceHeader, data)
                    response = struct_from_binary(ua.OpenSecureChannelResponse, data)
                    token = response.Parameters.SecurityToken
                    self.conn.security_token.ChannelId = token.ChannelId
                    self.conn.security_token.TokenId = token.TokenId
                    return Answer("OPN", status=response.ResponseHeader.ServiceResult.value,
                                  request_id=sequence.RequestId)
                if kind not in (b"MSG", b"CLO"):
                    return Answer("garbled")
                sequence = struct.unpack_from("<II", rest, 8)
                parts.append(rest[16:])
                if chunk == b"C":
                    continue
                if chunk == b"A":
                    return Answer("aborted", request_id=sequence[1])
                body = b"".join(parts)
                data = Buffer(body)
                typeid = nodeid_from_binary(data)
                header = struct_from_binary(ua.ResponseHeader, data)
                return Answer("MSG", status=header.ServiceResult.value, typeid=int(typeid.Identifier),
                              request_id=sequence[1], body=body)
        except (asyncio.IncompleteReadError, ConnectionError):
            return Answer("closed")
        except TimeoutError:
            return Answer("silent")

    async def until(self, request_id: int, timeout_s: float) -> Answer:
        """Answers until the one to ``request_id`` (or an error, a close, silence)."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while True:
            got = await self.answer(max(0.0, deadline - loop.time()))
            if got.kind in ("MSG", "OPN") and got.request_id != request_id:
                self.skipped += 1
                continue
            return got

    async def ask(self, data: bytes, timeout_s: float = 5.0) -> Answer:
        self.send(data)
        return await self.until(self.request_id, timeout_s)

    async def handshake(self, host: str, port: int, user: str | None = None, password: str | None = None,
                        timeout_s: float = 5.0) -> Answer:
        """Hello, OpenSecureChannel, CreateSession, ActivateSession: the last answer (good when all went)."""
        await self.connect(host, port)
        self.send(self.hello())
        got = await self.answer(timeout_s)
        if got.kind != "ACK":
            return got
        got = await self.ask(self.open(), timeout_s)
        if got.kind != "OPN":
            return got
        got = await self.ask(self.create_session(), timeout_s)
        if not got.good:
            return got
        self.token = got.decode(ua.CreateSessionResponse).Parameters.AuthenticationToken
        return await self.ask(self.activate(user, password), timeout_s)

    async def subscribe(self, timeout_s: float = 5.0) -> Answer:
        got = await self.ask(self.create_subscription(), timeout_s)
        if got.good:
            self.subscription = got.decode(ua.CreateSubscriptionResponse).Parameters.SubscriptionId
        return got

    def close(self) -> None:
        if self.writer is not None:
            self.writer.transport.abort()
            self.writer = None


RESPONSE_TYPES = {name: _typeid(cls) for name, cls in (
    ("read", ua.ReadResponse), ("write", ua.WriteResponse), ("fault", ua.ServiceFault),
    ("activate", ua.ActivateSessionResponse), ("create_session", ua.CreateSessionResponse),
    ("publish", ua.PublishResponse), ("subscribe", ua.CreateSubscriptionResponse))}
