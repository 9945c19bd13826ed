"""A fleet's certificate authority, its members' certificates, and checks of certificate files.

Zenoh does the TLS; this module makes what it needs.  One authority per fleet signs a certificate
for the router (server and client use, named by the addresses agents dial), one per agent and one
per operator (client use).  The common name is the member's name: the router's access rules
match agents by it.  The organization is the fleet's name, so a certificate can say which fleet
it was made for.

The checks run before a session opens (fleet.wire.session), because Zenoh's own refusal of a
bad certificate is a failed handshake that names no file.
"""

from __future__ import annotations

import datetime
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from fleet.errors import FleetError

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
DEFAULT_VALIDITY_DAYS = 825  # the longest validity TLS clients commonly accept for a leaf


@dataclass(frozen=True)
class Member:
    """Whom a certificate is for: `name` (its common name), `server` for the router."""

    name: str
    server: bool = False
    addresses: tuple[str, ...] = ()  # names the router is dialled by (DNS names or IP addresses)


def cert_path(directory: Path, name: str) -> Path:
    return directory / f"{name}.pem"


def key_path(directory: Path, name: str) -> Path:
    return directory / f"{name}.key"


def _now() -> datetime.datetime:
    return datetime.datetime.now(datetime.UTC)


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> None:
    path.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    path.chmod(0o600)


def _name(common_name: str, fleet: str) -> x509.Name:
    return x509.Name(
        [x509.NameAttribute(NameOID.ORGANIZATION_NAME, fleet), x509.NameAttribute(NameOID.COMMON_NAME, common_name)]
    )


def create_authority(directory: Path, fleet: str, days: int = 3650) -> None:
    """Write ca.pem and ca.key into `directory` (which must not hold an authority yet)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = _name(f"fleet {fleet} authority", fleet)
    now = _now()
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                key_cert_sign=True,
                crl_sign=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    directory.mkdir(parents=True, exist_ok=True)
    _write_key(directory / CA_KEY, key)
    (directory / CA_CERT).write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def _load_authority(directory: Path) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    cert = read_certificate(directory / CA_CERT)
    try:
        key = serialization.load_pem_private_key((directory / CA_KEY).read_bytes(), password=None)
    except (OSError, ValueError) as error:
        raise FleetError(f"{directory / CA_KEY}: cannot read the authority's key: {error}") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise FleetError(f"{directory / CA_KEY}: not an elliptic-curve key")
    return cert, key


def _san(addresses: tuple[str, ...]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for address in addresses:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(address)))
        except ValueError:
            names.append(x509.DNSName(address))
    return x509.SubjectAlternativeName(names)


def issue(directory: Path, member: Member, days: int = DEFAULT_VALIDITY_DAYS, valid_from=None) -> None:
    """Write <name>.pem and <name>.key signed by the authority in `directory`."""
    ca_cert, ca_key = _load_authority(directory)
    fleet = organization(ca_cert)
    key = ec.generate_private_key(ec.SECP256R1())
    start = valid_from or _now() - datetime.timedelta(minutes=5)
    usages = [ExtendedKeyUsageOID.CLIENT_AUTH] + ([ExtendedKeyUsageOID.SERVER_AUTH] if member.server else [])
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(member.name, fleet))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(start + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.ExtendedKeyUsage(usages), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
            critical=False,
        )
    )
    # rustls refuses a certificate without a subject alternative name; a client's carries its name.
    builder = builder.add_extension(_san(member.addresses or (member.name,)), critical=False)
    cert = builder.sign(ca_key, hashes.SHA256())
    _write_key(key_path(directory, member.name), key)
    cert_path(directory, member.name).write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def read_certificate(path: Path) -> x509.Certificate:
    try:
        return x509.load_pem_x509_certificate(path.read_bytes())
    except OSError as error:
        raise FleetError(f"{path}: cannot read certificate: {error.strerror or error}") from None
    except ValueError:
        raise FleetError(f"{path}: not a PEM certificate") from None


def check_key(path: Path) -> None:
    try:
        serialization.load_pem_private_key(path.read_bytes(), password=None)
    except OSError as error:
        raise FleetError(f"{path}: cannot read private key: {error.strerror or error}") from None
    except (ValueError, TypeError):
        raise FleetError(f"{path}: not an unencrypted PEM private key") from None


def organization(cert: x509.Certificate) -> str:
    values = cert.subject.get_attributes_for_oid(NameOID.ORGANIZATION_NAME)
    return str(values[0].value) if values else "?"


def common_name(cert: x509.Certificate) -> str:
    values = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(values[0].value) if values else "?"


def loopback_only(cert: x509.Certificate) -> bool:
    """The certificate names only this computer (127.0.0.1, ::1, localhost): a router holding it
    cannot be verified by agents on other computers, which dial it by another address."""
    try:
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        return False
    ips = names.get_values_for_type(x509.IPAddress)
    hosts = names.get_values_for_type(x509.DNSName)
    return bool(ips or hosts) and all(ip.is_loopback for ip in ips) and all(host == "localhost" for host in hosts)


def check_certificate(path: Path, authority: Path | None) -> None:
    """Refuse (FleetError, naming the file) a certificate that is unreadable, not valid now, or
    not signed by `authority` (the CA certificate the same Zenoh config trusts)."""
    cert = read_certificate(path)
    now = _now()
    if cert.not_valid_after_utc < now:
        raise FleetError(f"{path}: certificate of {common_name(cert)!r} expired on {cert.not_valid_after_utc:%Y-%m-%d}")
    if cert.not_valid_before_utc > now:
        start = f"{cert.not_valid_before_utc:%Y-%m-%d %H:%M} UTC"
        raise FleetError(f"{path}: certificate of {common_name(cert)!r} is not valid before {start}")
    if authority is None:
        return
    ca = read_certificate(authority)
    try:
        cert.verify_directly_issued_by(ca)
    except (ValueError, TypeError, InvalidSignature):
        raise FleetError(
            f"{path}: certificate of {common_name(cert)!r} is for fleet {organization(cert)!r}: "
            f"not issued by the authority in {authority} (fleet {organization(ca)!r})"
        ) from None
