"""The Dask cluster a5mi starts is closed to anyone without the run's credentials.

The attack this guards against: code running on the grading machine (a student's program) finds the local
cluster's ports in ``/proc/net/tcp``, imports ``distributed`` and asks the scheduler, a worker or a nanny to run
``os.system``. Every listening port of the cluster (found the same way, from the process table) must refuse a
plain TCP connection, a TLS connection without a client certificate and one with a certificate of the
attacker's own; with the run's credentials the same connection works and a task runs. The HTTP servers Dask
opens anyway (dashboard, Prometheus, ``/info`` pages) answer 404 to everything.
"""

from __future__ import annotations

import asyncio
import json
import os
import ssl

import pytest

#: Seconds a connection that must succeed may take: a hang check, far above the fraction of a second an idle
#: machine needs, so that a TLS handshake on a machine busy with other work never crosses it.
HANG = 120


async def _identity(address: str, **connection_args: object) -> dict:
    from distributed.comm import connect

    async def ask() -> dict:
        comm = await connect(address, timeout=HANG, **connection_args)
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            await comm.close()

    return await asyncio.wait_for(ask(), 2 * HANG)


def _http_get(port: int, path: str) -> tuple[int, bytes]:
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=HANG) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, b""


def _listening_ports() -> set[int]:
    """TCP ports on 127.0.0.1 that this process and its children listen on (what ``/proc/net/tcp`` shows)."""
    import psutil

    me = psutil.Process()
    pids = {me.pid} | {c.pid for c in me.children(recursive=True)}
    return {c.laddr.port for c in psutil.net_connections("tcp")
            if c.status == psutil.CONN_LISTEN and c.pid in pids and c.laddr.ip == "127.0.0.1"}


def test_the_local_cluster_refuses_whoever_lacks_the_runs_credentials() -> None:
    from distributed import Client
    from distributed.security import Security

    from a5mi.runtime.cluster import start_client

    no_cert = ssl.create_default_context()
    no_cert.check_hostname = False
    no_cert.verify_mode = ssl.CERT_NONE
    own = Security.temporary().get_connection_args("client")  # a valid certificate, from another CA
    with start_client(2) as client:
        address = client.scheduler.address
        assert address.startswith("tls://127.0.0.1:")
        info = client.scheduler_info()
        cluster_ports = {int(a.rsplit(":", 1)[1]) for a in
                         [address, *info["workers"], *(w["nanny"] for w in info["workers"].values())]}
        http_ports = {info["services"]["dashboard"], *(w["services"]["dashboard"] for w in info["workers"].values())}
        ports = _listening_ports()
        assert len(cluster_ports) == 5 and cluster_ports | http_ports == ports
        for port in sorted(http_ports):
            for path in ("/", "/info/main/workers.html", "/metrics", "/health", "/json/identity.json", "/statics/"):
                assert _http_get(port, path)[0] == 404, (port, path)
            assert json.loads(_http_get(port, "/sitemap.json")[1]) == {"paths": ["/sitemap.json"]}
        right = client.security.get_connection_args("client")
        for port in sorted(cluster_ports):
            for scheme, args in (("tcp", {}), ("tls", {"ssl_context": no_cert}), ("tls", own)):
                with pytest.raises(OSError):
                    asyncio.run(_identity(f"{scheme}://127.0.0.1:{port}", **args))
        for port in sorted(cluster_ports):
            assert "type" in asyncio.run(_identity(f"tls://127.0.0.1:{port}", **right))
        # the attack as a student writes it: a Client of the port, and os.system submitted
        with pytest.raises(OSError):
            Client(f"tcp://127.0.0.1:{address.rsplit(':', 1)[1]}", timeout=3)
        with pytest.raises(OSError):
            Client(address, timeout=3, security=Security.temporary())
        assert client.submit(os.getpid).result() != os.getpid()  # the grader's own client still works
        with Client(address, timeout=HANG, security=client.security) as again:
            assert again.submit(lambda: 6 * 7).result() == 42


@pytest.mark.parametrize("address, tls, insecure, message", [
    ("tcp://10.0.0.1:8786", None, False, "a plain tcp:// scheduler lets anyone who reaches it run code on its "
     "workers; use tls:// with --tls-ca/--tls-cert/--tls-key, or --insecure-scheduler"),
    ("localhost:8786", None, False, "--scheduler expects tls://HOST:PORT, found 'localhost:8786'"),
    ("tls://10.0.0.1:8786", None, False, "give --tls-ca, --tls-cert and --tls-key"),
    ("tls://10.0.0.1:8786", ("/nonexistent/ca.pem", "c", "k"), False, "'/nonexistent/ca.pem' is not a file"),
])
def test_check_scheduler_refuses_unauthenticated_clusters(address: str, tls: tuple[str, str, str] | None,
                                                          insecure: bool, message: str) -> None:
    from a5mi.platform.errors import UsageError
    from a5mi.runtime.cluster import check_scheduler

    with pytest.raises(UsageError, match=message.replace("(", r"\(").replace(")", r"\)")):
        check_scheduler(address, tls, insecure)


def test_check_scheduler_accepts_tls_files_and_named_insecurity(tmp_path) -> None:
    from distributed.security import Security

    from a5mi.runtime.cluster import check_scheduler

    assert check_scheduler("tcp://10.0.0.1:8786", None, True) is None
    sec = Security.temporary()
    files = []
    for name, pem in (("ca.pem", sec.tls_ca_file), ("cert.pem", sec.tls_client_cert), ("key.pem", sec.tls_client_key)):
        (tmp_path / name).write_text(pem)
        files.append(str(tmp_path / name))
    got = check_scheduler("tls://10.0.0.1:8786", tuple(files), False)
    assert got.require_encryption and got.tls_ca_file == files[0] and got.tls_client_key == files[2]


def test_animate_renders_on_the_tls_cluster(variant: str, tmp_path) -> None:
    """``a5mi animate --workers 2`` runs its frames on the same TLS cluster: they equal the in-process frames."""
    from a5mi import PROJECT_ROOT
    from a5mi.cli import run_a5mi
    from a5mi.platform.imageio import read_uint8

    scene = str(PROJECT_ROOT / "scenes" / "animation.txt")
    common = ["--frames", "0:3", "-size", "16", "16"]
    assert run_a5mi(["animate", scene, "-o", str(tmp_path / "one"), *common]) == 0
    assert run_a5mi(["animate", scene, "-o", str(tmp_path / "dask"), "--workers", "2", *common]) == 0
    names = sorted(p.name for p in (tmp_path / "one").glob("frame_*.png"))
    assert len(names) == 3 and names == sorted(p.name for p in (tmp_path / "dask").glob("frame_*.png"))
    for n in names:
        assert (read_uint8(tmp_path / "one" / n) == read_uint8(tmp_path / "dask" / n)).all(), n
