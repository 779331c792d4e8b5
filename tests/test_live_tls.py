"""Mutual TLS between the live nodes (``--tls-ca``, ``--tls-certificate``, ``--tls-key``): a peer
without a certificate of the session's authority is not connected; the flags are refused in
part, with a file that is none, or beside an endpoint TLS does not authenticate."""

from __future__ import annotations

import contextlib
import json
import os
import time
from pathlib import Path

import pytest

from ports import free_ports

pytest.importorskip("zenoh")
pytest.importorskip("cryptography")

from certificates import certificates  # noqa: E402 - needs cryptography
from delaytrack.cli import main  # noqa: E402
from delaytrack.live.tls import PeerCertificates  # noqa: E402
from delaytrack.live.transport import open_session  # noqa: E402

SCENARIO = "two_link_S1"


def test_only_a_peer_with_a_certificate_of_the_sessions_authority_is_connected(tmp_path):
    session = PeerCertificates(*certificates(tmp_path / "session"))
    # Another peer knows the session's authority (its certificate is public), so it can check
    # the node's certificate, but holds a certificate of another authority.
    _ca, certificate, key = certificates(tmp_path / "other", "another authority")
    other = PeerCertificates(session.ca, certificate, key)
    endpoint = f"tls/localhost:{free_ports(1)[0]}"
    received: list[bytes] = []
    node = open_session([endpoint], [], session)
    peers = {
        name: open_session([], [endpoint], c) for name, c in (("own", session), ("other", other))
    }
    try:
        node.declare_subscriber(
            "delaytrack/t/release", lambda s: received.append(s.payload.to_bytes())
        )
        deadline = time.monotonic() + 30.0
        while b"own" not in received and time.monotonic() < deadline:
            for name, peer in peers.items():
                peer.put("delaytrack/t/release", name.encode())
            time.sleep(0.05)
        for _ in range(10):  # the other peer's retries have had their time too
            for name, peer in peers.items():
                peer.put("delaytrack/t/release", name.encode())
            time.sleep(0.05)
    finally:
        for peer in (*peers.values(), node):
            peer.close()
    assert b"own" in received and b"other" not in received


def test_the_shared_session_ran_with_mutual_tls_and_its_report_says_so(live_run):
    folder, launched = live_run
    assert launched.outcome[2] == 0, launched.outcome[1].decode()
    for role in ("controller", "delay", "robot"):
        assert json.loads((folder / f"{role}.json").read_text())["mutual_tls"] is True
    assert (
        "mutual TLS: every peer authenticated by its certificate"
        in (folder / "report.html").read_text()
    )


def _listening_ports() -> set[tuple[str, int]]:
    """The TCP and UDP ports this process listens on (Linux)."""
    sockets = set()
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):
            link = os.readlink(f"/proc/self/fd/{fd}")
            if link.startswith("socket:["):
                sockets.add(link[len("socket:[") : -1])
    ports = set()
    for table in ("tcp", "tcp6", "udp", "udp6"):
        for line in Path(f"/proc/self/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            listening = table.startswith("udp") or fields[3] == "0A"
            if fields[9] in sockets and listening:
                ports.add((table, int(fields[1].rsplit(":", 1)[1], 16)))
    return ports


@pytest.mark.skipif(not Path("/proc/self/net/tcp").exists(), reason="needs Linux's /proc")
def test_with_certificates_a_node_listens_on_its_tls_endpoints_only(tmp_path):
    # Zenoh's default for a session without endpoints to listen on is TCP on every interface:
    # a node that only connected took unauthenticated peers there, and linked them to the rest.
    session = PeerCertificates(*certificates(tmp_path / "session"))
    port = free_ports(1)[0]
    before = _listening_ports()
    opened = [open_session([f"tls/localhost:{port}"], [], session)]
    try:
        opened.append(open_session([], [f"tls/localhost:{port}"], session))
        time.sleep(0.5)  # linked
        assert {port for _table, port in _listening_ports() - before} == {port}
    finally:
        for node in opened:
            node.close()


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--tls-ca", "{ca}"], "--tls-certificate and --tls-key must be given with --tls-ca"),
        (
            ["--tls-ca", "", "--tls-certificate", "", "--tls-key", ""],
            "--tls-ca is empty: give the path of its file",
        ),
        (
            [
                "--tls-ca",
                "{ca}",
                "--tls-certificate",
                "{other_certificate}",
                "--tls-key",
                "{other_key}",
            ],
            "is not accepted by a node holding --tls-ca '{ca}': unable to get local issuer",
        ),
        (
            ["--tls-ca", "{ca}", "--tls-certificate", "{certificate}", "--tls-key", "{other_key}"],
            "--tls-key '{other_key}' cannot be used together (KEY_VALUES_MISMATCH)",
        ),
        (  # swapped: OpenSSL gives no reason; its own text stands for it (it read "(None)")
            ["--tls-ca", "{ca}", "--tls-certificate", "{key}", "--tls-key", "{certificate}"],
            "--tls-key '{certificate}' cannot be used together ([SSL] PEM lib",
        ),
        (
            ["--tls-ca", "{key}", "--tls-certificate", "{certificate}", "--tls-key", "{key}"],
            "--tls-ca '{key}' holds no certificate of an authority that can be read",
        ),
        (
            ["--tls-ca", "{ca}", "--tls-certificate", "{certificate}", "--tls-key", "{missing}"],
            "--tls-key '{missing}' does not exist",
        ),
        (
            ["--tls-ca", "{folder}", "--tls-certificate", "{certificate}", "--tls-key", "{key}"],
            "--tls-ca '{folder}' is not a file but a folder",
        ),
    ],
)
@pytest.mark.parametrize("command", ["run", "robot"])
def test_tls_flags_in_part_or_naming_no_file_are_refused_in_one_line(
    capsys, tmp_path, command, flags, message
):
    ca, certificate, key = certificates(tmp_path / "tls")
    _other_ca, other_certificate, other_key = certificates(tmp_path / "other", "another authority")
    names = {"ca": ca, "certificate": certificate, "key": key, "folder": str(tmp_path)}
    names |= {"other_certificate": other_certificate, "other_key": other_key}
    names["missing"] = str(tmp_path / "missing.key")
    argv = ["live", command, SCENARIO, "--out", str(tmp_path / "out")]
    argv += [flag.format(**names) for flag in flags]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message.format(**names) in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("endpoint", ["tcp/127.0.0.1:7447", "tls/localhost:7447#enable_mtls=false"])
@pytest.mark.parametrize("flag", ["--listen", "--connect"])
def test_an_endpoint_tls_does_not_authenticate_is_refused_with_the_tls_flags(
    capsys, tmp_path, flag, endpoint
):
    ca, certificate, key = certificates(tmp_path / "tls")
    argv = ["live", "delay", SCENARIO, "--out", str(tmp_path / "out"), flag, endpoint]
    argv += ["--tls-ca", ca, "--tls-certificate", certificate, "--tls-key", key]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{flag} {endpoint!r}: with --tls-ca every endpoint must be tls/" in err
    assert not (tmp_path / "out").exists()


def test_an_encrypted_key_is_refused_not_asked_a_passphrase_for(capsys, tmp_path):
    from cryptography.hazmat.primitives import serialization

    ca, certificate, key = certificates(tmp_path / "tls")
    loaded = serialization.load_pem_private_key(Path(key).read_bytes(), password=None)
    encrypted = tmp_path / "encrypted.key"
    encrypted.write_bytes(
        loaded.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.BestAvailableEncryption(b"secret"),
        )
    )
    argv = ["live", "robot", SCENARIO, "--out", str(tmp_path / "out"), "--tls-ca", ca]
    argv += ["--tls-certificate", certificate, "--tls-key", str(encrypted)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot be used together" in err and "not encrypted" in err
