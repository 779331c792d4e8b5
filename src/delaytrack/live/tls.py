"""Mutual TLS between the live nodes: the files each node is given, and their check before the
node starts.

With ``--tls-ca``, ``--tls-certificate`` and ``--tls-key`` every link between the nodes is TLS
on which each end presents its certificate and checks the other's against the session's
authority (:func:`delaytrack.live.transport.zenoh_config`). Zenoh would find a certificate it
cannot use only when a link is attempted, which for a node that only connects means retrying
until the handshake gives up. :func:`check_certificates` finds it at once: Python's :mod:`ssl`
(OpenSSL) runs a mutual TLS handshake in memory between two ends holding the node's
certificate, each checking the other against the authority.
"""

from __future__ import annotations

import ssl
from typing import NamedTuple

__all__ = ["TLS_PROTOCOLS", "PeerCertificates", "check_certificates"]

#: The endpoints whose links TLS authenticates.
TLS_PROTOCOLS = ("tls", "quic")


class PeerCertificates(NamedTuple):
    """The files of mutual TLS between the nodes (PEM): ``ca``, the certificate of the
    authority that signed every node's certificate; ``certificate`` and ``key``, this node's
    certificate (naming the host it is reached at) and private key."""

    ca: str
    certificate: str
    key: str


def _end(certificates: PeerCertificates, server: bool) -> ssl.SSLContext:
    """One end of a link: it presents the node's certificate and requires the other's, signed
    by the authority (the names are Zenoh's to check, against the endpoints)."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER if server else ssl.PROTOCOL_TLS_CLIENT)
    context.check_hostname = False
    context.verify_mode = ssl.CERT_REQUIRED
    try:
        context.load_verify_locations(cafile=certificates.ca)
    except (ssl.SSLError, OSError) as error:
        raise ValueError(
            f"--tls-ca {certificates.ca!r} holds no certificate of an authority that can be read "
            f"({_reason(error)}); give the authority's certificate in PEM"
        ) from None
    try:  # an encrypted key is refused, not asked a passphrase for (Zenoh cannot read it)
        context.load_cert_chain(certificates.certificate, certificates.key, password=b"")
    except (ssl.SSLError, OSError) as error:
        raise ValueError(
            f"--tls-certificate {certificates.certificate!r} and --tls-key "
            f"{certificates.key!r} cannot be used together ({_reason(error)}); give the node's "
            "certificate and its own private key, in PEM, not encrypted"
        ) from None
    return context


def _reason(error: ssl.SSLError | OSError) -> str:
    """Why OpenSSL or the system refused a file, in words: its reason, its error text, or,
    where it gives neither (a certificate and a key swapped), the error's own text."""
    reason = error.reason if isinstance(error, ssl.SSLError) else error.strerror
    return str(reason) if reason else (str(error) or type(error).__name__)


def check_certificates(certificates: PeerCertificates) -> None:
    """Refuse node certificates that no peer of the session would accept: unreadable, not the
    key's, not signed by the authority, expired or not yet valid, or not made for both ends of a
    link (server and client authentication).

    Raises
    ------
    ValueError
        One line naming the file and OpenSSL's reason.
    """
    server = _end(certificates, server=True)
    client = _end(certificates, server=False)
    to_server, to_client = ssl.MemoryBIO(), ssl.MemoryBIO()
    ends = [
        server.wrap_bio(to_server, to_client, server_side=True),
        client.wrap_bio(to_client, to_server, server_side=False),
    ]
    done = [False, False]
    for _ in range(20):  # a TLS 1.3 handshake takes a few rounds
        for i, end in enumerate(ends):
            if done[i]:
                continue
            try:
                end.do_handshake()
                done[i] = True
            except ssl.SSLWantReadError:
                pass
            except ssl.SSLCertVerificationError as error:
                raise ValueError(
                    f"--tls-certificate {certificates.certificate!r} is not accepted by a node "
                    f"holding --tls-ca {certificates.ca!r}: {error.verify_message}; give a "
                    "certificate that authority signed, valid now, for server and client "
                    "authentication"
                ) from None
            except ssl.SSLError as error:
                raise ValueError(
                    f"--tls-certificate {certificates.certificate!r} cannot make a TLS link "
                    f"with --tls-ca {certificates.ca!r}: {error.reason or error}"
                ) from None
        if all(done):
            return
    raise ValueError(  # not reached with OpenSSL's handshakes; said rather than hung
        f"--tls-certificate {certificates.certificate!r}: a TLS handshake with itself did not end"
    )
