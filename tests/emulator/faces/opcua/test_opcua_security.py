"""The OPC UA face's security: signed and encrypted endpoints (asyncua's client and node-opcua-client),
which client certificates are accepted, anonymous logins off, the server certificate kept across a
restart with --state, and bad settings in one line."""

from __future__ import annotations

import asyncio
import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.ua.uaerrors import UaError
from cryptography.x509.oid import ExtendedKeyUsageOID
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua.settings import SECURITY, OpcUaSettings
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine, parse_machine
from nckemu.errors import NckConfigError

pytestmark = pytest.mark.timeout(180)
NODE_DIR = Path(__file__).parent / "node_opcua"
NODE = shutil.which("node")
USERS = '[opcua.users.nckemu]\npassword = "SUNRISE"\nrights = ["SinuReadAll", "SinuWriteAll"]\n'


def _machine(tmp_path: Path, opcua: str = "") -> Path:
    path = tmp_path / "machine.toml"
    path.write_text(f'name = "secure mill"\n[plc]\ndata_blocks = {{ 130 = 64 }}\n[opcua]\n{opcua}\n{USERS}',
                    encoding="utf-8")
    return path


async def _client_certificate(where: Path, name: str = "client") -> tuple[Path, Path]:
    where.mkdir(parents=True, exist_ok=True)
    certificate, key = where / f"{name}.der", where / f"{name}.pem"
    # the URI asyncua's client announces (the server checks the certificate names it)
    await setup_self_signed_certificate(key, certificate, "urn:example.org:FreeOpcUa:opcua-asyncio", "localhost",
                                        [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": name})
    return certificate, key


async def _write_read(face: OpcUaFace, security: str | None, user: str | None = "nckemu") -> list[Any]:
    client = Client(face.url, timeout=10)
    if security:
        await client.set_security_string(security)
    if user:
        client.set_user(user)
        client.set_password("SUNRISE")
    async with client:
        ns = await client.get_namespace_index("SinumerikVarProvider")
        node = client.get_node(ua.NodeId("/Plc/DB130.DBW2", ns))
        if user:
            await node.write_value(ua.Variant(4242, ua.VariantType.UInt16))
        return [await node.read_value(), client.security_policy.URI]


async def _serving(machine: Path, state: Path | None = None) -> OpcUaFace:
    return await OpcUaFace(Emulator(load_machine(machine), state_path=state), "127.0.0.1", 0).start()


@pytest.mark.parametrize("policy", ["Basic256Sha256", "Aes128Sha256RsaOaep", "Aes256Sha256RsaPss"])
def test_signed_and_encrypted_sessions_read_and_write(tmp_path: Path, policy: str) -> None:
    async def go() -> list[Any]:
        certificate, key = await _client_certificate(tmp_path / "client")
        face = await _serving(_machine(tmp_path), tmp_path / "state.json")
        try:
            encrypted = await _write_read(face, f"{policy},SignAndEncrypt,{certificate},{key}")
            signed = await _write_read(face, f"{policy},Sign,{certificate},{key}")
            return [encrypted, signed, await _write_read(face, None)]
        finally:
            await face.stop()

    encrypted, signed, plain = asyncio.run(go())
    assert encrypted[0] == 4242 and encrypted[1].rsplit("#", 1)[1].replace("_", "") == policy
    assert signed[0] == 4242 and plain == [4242, "http://opcfoundation.org/UA/SecurityPolicy#None"]


def test_only_trusted_client_certificates_when_not_accepting_any(tmp_path: Path) -> None:
    async def go() -> tuple[list[Any], str]:
        trusted_cert, trusted_key = await _client_certificate(tmp_path / "client", "trusted")
        other_cert, other_key = await _client_certificate(tmp_path / "client", "stranger")
        (tmp_path / "trusted").mkdir()
        shutil.copy(trusted_cert, tmp_path / "trusted" / trusted_cert.name)
        machine = _machine(tmp_path, 'accept_certificates = false\ntrusted_certificates = "trusted"')
        face = await _serving(machine)
        try:
            accepted = await _write_read(face, f"Basic256Sha256,SignAndEncrypt,{trusted_cert},{trusted_key}")
            try:
                await _write_read(face, f"Basic256Sha256,SignAndEncrypt,{other_cert},{other_key}")
                refused = "accepted"
            except (TimeoutError, UaError, ConnectionError) as exc:
                refused = type(exc).__name__
            return accepted, refused
        finally:
            await face.stop()

    accepted, refused = asyncio.run(go())
    assert accepted[0] == 4242
    assert refused != "accepted"


def test_anonymous_logins_can_be_switched_off(tmp_path: Path) -> None:
    async def go() -> tuple[str, set[Any], list[Any]]:
        face = await _serving(_machine(tmp_path, "allow_anonymous = false"))
        try:
            async with Client(face.url, timeout=10) as probe:  # discovery needs no session
                endpoints = await probe.get_endpoints()
        except UaError:
            endpoints = await Client(face.url, timeout=10).connect_and_get_server_endpoints()
        try:
            try:
                await _write_read(face, None, user=None)
                anonymous = "accepted"
            except UaError as exc:
                anonymous = type(exc).__name__
            offered = {token.TokenType for endpoint in endpoints for token in endpoint.UserIdentityTokens}
            return anonymous, offered, await _write_read(face, None)
        finally:
            await face.stop()

    anonymous, offered, user = asyncio.run(go())
    assert anonymous != "accepted"
    assert ua.UserTokenType.Anonymous not in offered and ua.UserTokenType.UserName in offered
    assert user[0] == 4242


def test_the_server_certificate_survives_a_restart_with_state(tmp_path: Path) -> None:
    async def certificate_of(face: OpcUaFace) -> bytes:
        async with Client(face.url, timeout=10) as client:
            endpoints = await client.get_endpoints()
        secured = [e.ServerCertificate for e in endpoints if e.SecurityMode != ua.MessageSecurityMode.None_]
        assert secured and len(set(secured)) == 1
        return secured[0]

    async def go() -> list[bytes]:
        seen = []
        for _ in range(2):
            face = await _serving(_machine(tmp_path), tmp_path / "state.json")
            try:
                seen.append(await certificate_of(face))
            finally:
                await face.stop()
        return seen

    first, second = asyncio.run(go())
    assert first == second
    assert (tmp_path / "state.opcua-pki" / "server_certificate.der").read_bytes() == first


@pytest.mark.parametrize(("table", "field"), [
    ('security = ["Basic512"]', "opcua.security"),
    ("security = []", "opcua.security"),
    ('allow_anonymous = "no"', "opcua.allow_anonymous"),
    ("accept_certificates = false", "opcua.accept_certificates"),
    ('trusted_certificates = "nowhere"', "opcua.trusted_certificates"),
    ('certificate = "machine.toml"', "opcua.certificate"),
])
def test_bad_security_settings_name_the_field(tmp_path: Path, table: str, field: str) -> None:
    with pytest.raises(NckConfigError) as caught:
        OpcUaSettings.from_machine(parse_machine(_machine(tmp_path, table).read_text()).opcua,
                                   str(tmp_path / "machine.toml"))
    assert f"field '{field}'" in str(caught.value) and "machine.toml" in str(caught.value)


@given(st.lists(st.sampled_from(SECURITY), min_size=1), st.booleans())
def test_security_lists_parse_to_the_policies_named(policies: list[str], anonymous: bool) -> None:
    settings = OpcUaSettings.from_machine({"security": policies, "allow_anonymous": anonymous}, "m.toml")
    assert settings.security == tuple(dict.fromkeys(policies)) and settings.allow_anonymous is anonymous


@pytest.mark.skipif(NODE is None or not (NODE_DIR / "node_modules" / "node-opcua-client").is_dir(),
                    reason="node-opcua-client is not installed: run `make npm` (make test does)")
def test_node_opcua_client_with_sign_and_encrypt(tmp_path: Path) -> None:
    async def go() -> Any:
        face = await _serving(_machine(tmp_path), tmp_path / "state.json")
        try:
            job = {"url": face.url, "user": "nckemu", "password": "SUNRISE", "security": "Basic256Sha256",
                   "mode": "SignAndEncrypt", "pki": str(tmp_path / "node-pki"),
                   "ops": [{"write": "ns=2;s=/Plc/DB130.DBW2", "value": 777, "type": "UInt16"},
                           {"read": "ns=2;s=/Plc/DB130.DBW2"}]}
            done = await asyncio.to_thread(subprocess.run, [str(NODE), str(NODE_DIR / "client.js"), json.dumps(job)],
                                           capture_output=True, text=True, timeout=120, cwd=NODE_DIR)
            lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
            assert lines, done.stdout[-2000:] + done.stderr[-2000:]
            return json.loads(lines[-1][len("RESULT "):])
        finally:
            await face.stop()

    assert asyncio.run(go()) == [{"status": "Good"}, {"status": "Good", "value": 777}]
