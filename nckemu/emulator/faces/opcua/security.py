"""Security of the OPC UA face: which policies its endpoints offer, the server's certificate, which
client certificates it accepts and whether anonymous logins exist.

The controller offers "encryption None, 128 bit or 256 bit", "accept certificates automatically" and
"allow anonymous access" (its setup manual). Here:
- the policies of the ``[opcua] security`` list (``settings.SECURITY``, all by default);
- the server's certificate and key from the machine file (``certificate``, ``private_key``), or made at
  the first start and kept: beside the retained state (``serve --state S.json``: ``S.opcua-pki/``),
  else under the cache directory (``~/.cache/nckemu/pki/<machine>/``), so that a client which pinned it
  keeps trusting it across restarts;
- any client certificate (``accept_certificates = true``, the default), or only those in the
  ``trusted_certificates`` directory; others get asyncua's BadSecurityChecksFailed at CreateSession;
- ``allow_anonymous = false``: the endpoints offer user name and certificate tokens only.
"""

from __future__ import annotations

import logging
import re
import socket
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua
from asyncua.crypto import uacrypto
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from cryptography.x509.oid import ExtendedKeyUsageOID

from nckemu.emulator.faces.opcua import asyncua_internals
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.faces.opcua.shelf import cache_root
from nckemu.errors import NckConfigError

if TYPE_CHECKING:
    from nckemu.emulator.machine.core import Emulator

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.security")

CERTIFICATE_FILE = "server_certificate.der"
KEY_FILE = "server_key.pem"


def policy_types(settings: OpcUaSettings) -> list[ua.SecurityPolicyType]:
    return [ua.SecurityPolicyType.NoSecurity if name == "None" else getattr(ua.SecurityPolicyType, name)
            for name in settings.security]


def application_uri(emulator: Emulator) -> str:
    return f"urn:nckemu:{_safe(emulator.name)}"


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "machine"


def pki_dir(emulator: Emulator) -> Path:
    """Where the made certificate is kept (made if missing; a temporary directory when nothing else
    can be written)."""
    candidates: list[Path] = []
    if emulator.store is not None:
        state = Path(emulator.store.path)
        candidates.append(state.parent / f"{state.stem}.opcua-pki")
    root = cache_root()
    if root is not None:
        candidates.append(root / "pki" / _safe(emulator.name))
    for where in candidates:
        try:
            where.mkdir(parents=True, exist_ok=True)
            return where
        except OSError:
            continue
    return Path(tempfile.mkdtemp(prefix="nckemu-opcua-pki-"))


# The certificates and keys the faces of this process loaded, by their files (path, size, mtime), the
# application URI and the host: parsing the RSA key costs ~60 ms (OpenSSL checks it) and asyncua parsed
# it twice a start (its certificate check, then the load); a fleet or a test run starts faces by the
# hundred. Files changed on disk are other files here and are loaded again.
_LOADED: dict[tuple[Any, ...], tuple[Any, Any]] = {}


def _files_stamp(*paths: Path) -> tuple[Any, ...] | None:
    try:
        return tuple((str(path), stat.st_size, stat.st_mtime_ns) for path in paths for stat in [path.stat()])
    except OSError:
        return None


async def _load_certificate(server: Server, emulator: Emulator, settings: OpcUaSettings, uri: str) -> None:
    made = not (settings.certificate and settings.private_key)
    if made:
        where = pki_dir(emulator)
        certificate, key = where / CERTIFICATE_FILE, where / KEY_FILE
    else:
        certificate, key = Path(str(settings.certificate)), Path(str(settings.private_key))
    host = socket.gethostname()
    stamp = _files_stamp(certificate, key)
    held = _LOADED.get((stamp, uri, host)) if stamp is not None else None
    # a made certificate is checked as asyncua checks it (valid today, naming the URI and this host)
    if held is not None and made and uacrypto.check_certificate(held[0], uri, host):
        held = None
    if held is not None:
        asyncua_internals.use_certificate(server, *held)
        return
    if made:
        # asyncua checks that the certificate names this host (and makes a new one where it does not)
        await setup_self_signed_certificate(
            key, certificate, uri, host, [ExtendedKeyUsageOID.SERVER_AUTH],
            {"countryName": "DE", "organizationName": "nckemu", "commonName": f"nckemu {emulator.name}"})
        key.chmod(0o600)
    try:
        await server.load_certificate(str(certificate))
        await server.load_private_key(str(key))
    except (OSError, ValueError) as exc:
        raise NckConfigError(f"the OPC UA certificate or key does not load: {exc}", path=str(certificate),
                             field="opcua.certificate") from None
    stamp = _files_stamp(certificate, key)
    if stamp is not None:
        _LOADED[(stamp, uri, host)] = asyncua_internals.loaded_certificate(server)


async def apply(server: Server, emulator: Emulator, settings: OpcUaSettings, rules: Any) -> None:
    """Set the policies, the certificate, the validator and the identity tokens on an initialised server."""
    server.set_security_policy(policy_types(settings), permission_ruleset=rules)
    uri = application_uri(emulator)
    await server.set_application_uri(uri)
    if any(name != "None" for name in settings.security):
        await _load_certificate(server, emulator, settings, uri)
    if not settings.accept_certificates and settings.trusted_certificates:
        trust = TrustStore([Path(settings.trusted_certificates)], [])
        await trust.load()
        options = CertificateValidatorOptions.TRUSTED_VALIDATION | CertificateValidatorOptions.PEER_CLIENT
        server.set_certificate_validator(CertificateValidator(options, trust))
    tokens = [ua.UserNameIdentityToken, ua.X509IdentityToken]
    if settings.allow_anonymous:
        tokens.insert(0, ua.AnonymousIdentityToken)
    server.set_identity_tokens(tokens)
