"""Mutual TLS between the live nodes (``--tls-ca``, ``--tls-certificate``, ``--tls-key``): a peer
without a certificate of the session's authority is not connected; the flags are refused in
part, with a file that is none, or beside an endpoint TLS does not authenticate."""

from __future__ import annotations

import json
import time

import pytest

from delaytrack.live.session import _free_ports

pytest.importorskip("zenoh")
pytest.importorskip("cryptography")

from certificates import certificates  # noqa: E402 - needs cryptography
from delaytrack.cli import main  # noqa: E402
from delaytrack.live.transport import PeerCertificates, open_session  # noqa: E402

SCENARIO = "two_link_S1"


def test_only_a_peer_with_a_certificate_of_the_sessions_authority_is_connected(tmp_path):
    session = PeerCertificates(*certificates(tmp_path / "session"))
    # Another peer knows the session's authority (its certificate is public), so it can check
    # the node's certificate, but holds a certificate of another authority.
    _ca, certificate, key = certificates(tmp_path / "other", "another authority")
    other = PeerCertificates(session.ca, certificate, key)
    endpoint = f"tls/localhost:{_free_ports(1)[0]}"
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


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--tls-ca", "{ca}"], "--tls-certificate and --tls-key must be given with --tls-ca"),
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
    names = {"ca": ca, "certificate": certificate, "key": key, "folder": str(tmp_path)}
    names["missing"] = str(tmp_path / "missing.key")
    argv = ["live", command, SCENARIO, "--out", str(tmp_path / "out")]
    argv += [flag.format(**names) for flag in flags]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message.format(**names) in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("flag", ["--listen", "--connect"])
def test_an_endpoint_tls_does_not_authenticate_is_refused_with_the_tls_flags(
    capsys, tmp_path, flag
):
    ca, certificate, key = certificates(tmp_path / "tls")
    argv = ["live", "delay", SCENARIO, "--out", str(tmp_path / "out"), flag, "tcp/127.0.0.1:7447"]
    argv += ["--tls-ca", ca, "--tls-certificate", certificate, "--tls-key", key]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{flag} 'tcp/127.0.0.1:7447': with --tls-ca every endpoint must be tls/" in err
    assert not (tmp_path / "out").exists()
