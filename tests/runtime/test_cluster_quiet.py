"""a5mi's local Dask cluster says nothing on the grader's terminal when port 8787 is taken (docs/GRADING.md
"Across machines"): its scheduler's HTTP server takes a free loopback port instead of trying 8787."""

from __future__ import annotations

import contextlib
import socket
import warnings

import pytest

pytest.importorskip("distributed")


def test_no_port_8787_warning_beside_another_cluster() -> None:
    from a5mi.runtime.cluster import start_client

    holder = socket.socket()
    with contextlib.suppress(OSError):  # 8787 held by this test, or already by someone else: taken either way
        holder.bind(("127.0.0.1", 8787))
        holder.listen(1)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with start_client(1) as client:
                info = client.scheduler_info()
                assert client.submit(sum, [1, 2]).result() == 3
    finally:
        holder.close()
    assert not [w for w in caught if "already in use" in str(w.message)], [str(w.message) for w in caught]
    port = info["services"]["dashboard"]
    assert port != 8787 and info["address"].startswith("tls://127.0.0.1:")
