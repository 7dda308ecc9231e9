"""Units of work on a Dask cluster, journaled on disk; the cluster's traffic authenticated by TLS.

* :class:`Journal`: one JSON record per line, appended and ``fsync``-ed as each result arrives; a torn last
  line (the grader killed mid-write) is ignored on reading. ``done()`` = the keys already recorded, or, given
  each key's *fingerprint* (a digest of everything that decides the unit's result), only the keys whose
  record carries that same fingerprint.
* :func:`start_client`: a ``distributed.LocalCluster`` of ``workers`` single-threaded worker **processes**
  bound to 127.0.0.1 (no dashboard; the scheduler's HTTP server on a free loopback port, never 8787), or,
  with ``scheduler="tls://HOST:PORT"``, a client of an existing cluster (``dask scheduler`` / ``dask
  worker``, or ``dask-jobqueue`` on SLURM).
* **Authentication.** Whoever can open a connection to a Dask scheduler, worker or nanny can make it run
  any Python function. The local cluster therefore speaks only ``tls://`` with mutual authentication and
  per-run credentials (:func:`per_run_security`: a fresh self-signed key and certificate, in memory only,
  which is both the CA and every role's certificate): a process that finds a port in ``/proc/net/tcp`` and
  lacks the run's key is refused at the TLS handshake, whatever it sends. The HTTP servers Dask's scheduler and
  workers always open (dashboard, Prometheus, ``/info`` pages with worker logs and call stacks) get no routes:
  every request is answered 404. An existing cluster is joined with
  the user's credentials (:func:`user_security`, or the ``distributed.comm.tls`` section of the Dask
  configuration); :func:`check_scheduler` refuses a plain ``tcp://`` one unless asked by name.
* :func:`run_units`: submit one Dask task per unit not yet in the journal (``resume``; with ``fingerprints``
  a journaled record whose fingerprint differs is run again), each with ``retries``; a worker that dies
  (killed, out of memory) loses nothing: the scheduler hands its tasks to another worker (the nanny restarts
  the dead one) and only finished results reach the journal. Results are returned in completion order with
  the journaled ones.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from a5mi.platform import interrupts
from a5mi.platform.errors import UsageError, UserError
from a5mi.runtime.extras import require

Progress = Callable[[int, int], None]
#: Seconds Dask is given to close the client and the local cluster (then its workers are killed).
CLOSE_TIMEOUT = 20


class Journal:
    """Append-only JSON-lines file of result records keyed by ``record["key"]``."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)

    def records(self) -> list[dict[str, Any]]:
        """Every complete record, later records of a key replacing earlier ones (insertion order kept)."""
        if not self.path.is_file():
            return []
        out: dict[str, dict[str, Any]] = {}
        with open(self.path, encoding="utf-8") as f:
            for line in f:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a torn last line
                if isinstance(rec, dict) and "key" in rec:
                    out[rec["key"]] = rec
        return list(out.values())

    def done(self, fingerprints: Mapping[str, str] | None = None) -> set[str]:
        """The keys recorded; with ``fingerprints``, only those whose record has ``fingerprints[key]`` as its
        ``"fingerprint"`` (a record of a changed unit, or one written without a fingerprint, is not done)."""
        if fingerprints is None:
            return {r["key"] for r in self.records()}
        return {r["key"] for r in self.records()
                if r["key"] in fingerprints and r.get("fingerprint") == fingerprints[r["key"]]}

    def append(self, record: dict[str, Any]) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        line = json.dumps(record, allow_nan=False, default=str) + "\n"
        with open(self.path, "ab") as f:
            if f.tell() > 0:
                with open(self.path, "rb") as r:
                    r.seek(-1, os.SEEK_END)
                    if r.read(1) != b"\n":
                        line = "\n" + line  # end a torn last line so this record stays readable
            f.write(line.encode("utf-8"))
            f.flush()
            os.fsync(f.fileno())

    def reset(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()


def per_run_security() -> Any:
    """A ``distributed.security.Security`` with a fresh self-signed RSA-2048 key and certificate, used as the CA
    and as the scheduler's, workers' and client's certificate (``Security.temporary()``; needs the
    ``cryptography`` package, in the ``grade`` and ``animate`` extras), ``require_encryption`` set: the
    credentials of one run, kept in memory."""
    require("cryptography", "grade")  # Security.temporary() imports it lazily: fail with the one-line error
    return require("distributed", "grade").Security.temporary()


def user_security(ca: str, cert: str, key: str) -> Any:
    """The client ``Security`` of an existing TLS cluster: the CA that signed its certificates and this
    client's certificate and key (PEM files), ``require_encryption`` set."""
    security = require("distributed", "grade").Security
    return security(require_encryption=True, tls_ca_file=ca, tls_client_cert=cert, tls_client_key=key)


def spelled(flag: str, name: str) -> str:
    """The flag ``name`` (words joined by ``-``: ``insecure-scheduler``) in the spelling of ``flag``, the
    command's own ``--scheduler`` or ``a5``'s ``-scheduler``: ``--insecure-scheduler`` / ``-insecure_scheduler``."""
    return f"--{name}" if flag.startswith("--") else f"-{name.replace('-', '_')}"


def check_scheduler(address: str, tls: tuple[str, str, str] | None, insecure: bool, flag: str = "--scheduler") -> Any:
    """The client ``Security`` to join ``address`` (None: Dask's configuration decides), or a
    :class:`~a5mi.platform.errors.UsageError`: ``tcp://`` without ``insecure`` (anyone who reaches it can run code on
    its
    workers), ``tls://`` without credentials (``tls`` = (ca, cert, key) files, or the Dask configuration's
    ``distributed.comm.tls.ca-file``), credentials that are not files, or credentials for a ``tcp://``
    address. Messages name the flags in the spelling of ``flag`` (:func:`spelled`)."""
    dask = require("dask", "grade")

    ca, cert, key, unsafe = (spelled(flag, n) for n in ("tls-ca", "tls-cert", "tls-key", "insecure-scheduler"))
    scheme = address.partition("://")[0] if "://" in address else ""
    if scheme not in ("tcp", "tls", "inproc"):
        raise UsageError(f"{flag} expects tls://HOST:PORT, found '{address[:40]}'")
    if tls is not None:
        for path in tls:
            if not os.path.isfile(path):
                raise UsageError(f"TLS credential '{path}' is not a file")
    if scheme == "tcp":
        if tls is not None:
            raise UsageError(f"{flag} {address}: TLS credentials given for a tcp:// address (use tls://)")
        if not insecure:
            raise UsageError(f"{flag} {address}: a plain tcp:// scheduler lets anyone who reaches it run code on "
                             f"its workers; use tls:// with {ca}/{cert}/{key}, or {unsafe}")
        return None
    if scheme == "tls" and tls is None:
        if not dask.config.get("distributed.comm.tls.ca-file", None):
            raise UsageError(f"{flag} {address}: give {ca}, {cert} and {key} (or set "
                             f"distributed.comm.tls in the Dask configuration)")
        return None
    return None if tls is None else user_security(*tls)


def connect_timeout() -> float:
    """Seconds a connection to a scheduler may take, its handshake included: Dask's
    ``distributed.comm.timeouts.connect`` (30 s unless configured, e.g.
    ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``)."""
    dask = require("dask", "grade")   # dask's own import brings dask.config and dask.utils
    setting = dask.config.get("distributed.comm.timeouts.connect", "30s")
    return float(dask.utils.parse_timedelta(setting, default="seconds"))


def probe_scheduler(address: str, security: Any = None, timeout: float | None = None) -> None:
    """Connect to the scheduler at ``address`` and complete Dask's handshake within ``timeout`` seconds
    (:func:`connect_timeout`), then close; else :class:`~a5mi.platform.errors.UserError` in one line. Dask's own
    ``Client(timeout=...)`` bounds the TCP connect but not the handshake read, so a peer that accepts and never
    answers would hold the client for ever; this bound covers both."""
    import asyncio

    comm = require("distributed", "grade").comm
    t = connect_timeout() if timeout is None else timeout
    kwargs = {} if security is None else security.get_connection_args("client")

    async def attempt() -> None:
        c = await asyncio.wait_for(comm.connect(address, timeout=t, **kwargs), t)
        await c.close()

    scheme, _, rest = address.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme in ("tcp", "tls") and host and port.isdigit():
        import socket

        try:  # refused or unroutable: at once, not after Dask's retries for the whole limit
            socket.create_connection((host.strip("[]"), int(port)), timeout=t).close()
        except OSError as exc:
            raise UserError(f"scheduler {address[:80]}: cannot connect: {exc.strerror or exc}") from None
    try:
        asyncio.run(attempt())
    except TimeoutError:
        raise UserError(f"scheduler {address[:80]}: no Dask handshake within {t:g} s (is it a Dask scheduler?)") \
            from None
    except OSError as exc:
        raise UserError(f"scheduler {address[:80]}: cannot connect: {str(exc)[:160]}") from None


@contextlib.contextmanager
def start_client(workers: int = 2, scheduler: str | None = None, *,
                 memory_limit: str | None = "auto", security: Any = None) -> Iterator[Any]:
    """A ``distributed.Client``: of ``scheduler`` if given (with ``security``, else Dask's configuration),
    else of a fresh ``LocalCluster`` on ``tls://127.0.0.1`` with :func:`per_run_security` (module docstring);
    both are closed on exit."""
    dask, distributed = require("dask", "grade"), require("distributed", "grade")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    with dask.config.set({"distributed.scheduler.allowed-failures": 5, "distributed.worker.daemon": False,
                          "distributed.logging.distributed": "error"}):
        if scheduler is not None:
            if not scheduler.startswith("inproc://"):
                probe_scheduler(scheduler, security)
            try:
                client = Client(scheduler, timeout=connect_timeout(),
                                **({} if security is None else {"security": security}))
            except (OSError, TimeoutError) as exc:
                raise UserError(f"scheduler {scheduler[:80]}: {str(exc)[:160]}") from None
            try:
                yield client
            finally:
                client.close()
            return
        # A signal while the cluster starts or closes waits for it (interrupts.protected: Dask's own time-outs
        # bound both): a cluster left half-started or half-closed by an exception fails Dask's exit hook with
        # a traceback and leaves its workers' semaphores to the resource tracker's "leaked" warning.
        with interrupts.protected(), dask.config.set({"distributed.scheduler.http.routes": [],
                                                      "distributed.worker.http.routes": []}):
            # The scheduler always opens an HTTP server; dashboard_address=None means "port 8787", which warns
            # "Port 8787 is already in use" beside another cluster: port 0 on loopback, and no dashboard page.
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                                   protocol="tls://", security=per_run_security(), dashboard_address="127.0.0.1:0",
                                   scheduler_kwargs={"dashboard": False}, worker_dashboard_address=None,
                                   memory_limit=memory_limit, silence_logs=50)
            client = Client(cluster)
        try:
            yield client
        finally:
            with interrupts.protected():
                client.close(timeout=CLOSE_TIMEOUT)
                cluster.close(timeout=CLOSE_TIMEOUT)


def run_units(client: Any, units: Sequence[tuple[str, Any]], fn: Callable[[Any], dict[str, Any]],
              journal: Journal, *, resume: bool = False, retries: int = 2,
              progress: Progress | None = None,
              on_record: Callable[[dict[str, Any]], None] | None = None,
              fingerprints: Mapping[str, str] | None = None) -> list[dict[str, Any]]:
    """Run ``fn(unit)`` for every ``(key, unit)`` on ``client`` (one task each), journaling each result dict
    (which gets ``"key"``, and ``"fingerprint"`` = ``fingerprints[key]`` when given); with ``resume`` the keys
    already journaled (with the same fingerprint, :meth:`Journal.done`) are not run again. Returns every
    record of these keys. A task that fails for good (its exception, or a worker dying more than
    ``allowed-failures`` times) is journaled as ``{"key", "error"}`` and not retried on resume. ``on_record``
    sees each new record as it is journaled."""
    as_completed = require("distributed", "grade").as_completed

    if not resume:
        journal.reset()
    done = journal.done(fingerprints)
    todo = [(k, u) for k, u in units if k not in done]
    total, finished = len(units), len(units) - len(todo)
    if progress is not None:
        progress(finished, total)
    futures = {client.submit(fn, u, key=f"a5mi-{k}-{os.getpid()}", retries=retries, pure=False): k
               for k, u in todo}
    for fut in as_completed(futures):
        key = futures[fut]
        try:
            rec = dict(fut.result())
        except Exception as exc:  # noqa: BLE001 - a unit's failure is a result, not the batch's end
            rec = {"error": f"{type(exc).__name__}: {exc}"}
        rec["key"] = key
        if fingerprints is not None:
            rec["fingerprint"] = fingerprints[key]
        journal.append(rec)
        if on_record is not None:
            on_record(rec)
        finished += 1
        if progress is not None:
            progress(finished, total)
    wanted = {k for k, _ in units}
    return [r for r in journal.records() if r["key"] in wanted]


__all__ = ["Journal", "Progress", "check_scheduler", "connect_timeout", "per_run_security", "probe_scheduler",
           "run_units", "spelled", "start_client", "user_security"]
