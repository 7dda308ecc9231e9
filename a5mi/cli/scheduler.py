"""How a command joins an existing Dask cluster (``--scheduler``; ``grade``, ``animate``, ``photons --ppm``): the
shared flags and the client credentials they make (docs/CLI.md, "-workers N / -scheduler URL")."""

from __future__ import annotations

from a5mi.cli.flags import Args, Flag, text
from a5mi.platform.errors import UsageError

#: How a command of ``--scheduler`` joins an existing Dask cluster (:func:`scheduler_security`; ``grade``,
#: ``animate``, ``photons``): TLS credentials, or the explicit opt-in to a plain ``tcp://`` scheduler.
SCHEDULER_FLAGS: tuple[Flag, ...] = (
    Flag(("--tls-ca",), "tls_ca", "with --scheduler tls://: the CA certificate of the cluster (PEM)", 1, text,
         metavar="FILE"),
    Flag(("--tls-cert",), "tls_cert", "with --scheduler tls://: this client's certificate (PEM)", 1, text,
         metavar="FILE"),
    Flag(("--tls-key",), "tls_key", "with --scheduler tls://: this client's private key (PEM)", 1, text,
         metavar="FILE"),
    Flag(("--insecure-scheduler",), "insecure_scheduler", "allow a plain tcp:// --scheduler (anyone who reaches "
         "it can run code on its workers)", default=False, show_default=False),
)


def scheduler_security(args: Args):  # noqa: ANN201 - distributed.security.Security or None
    """The client credentials of ``--scheduler`` (:func:`a5mi.runtime.cluster.check_scheduler`); TLS flags without
    ``--scheduler`` are a usage error."""
    from a5mi.runtime.cluster import check_scheduler

    given = [f for f, v in (("--tls-ca", args.tls_ca), ("--tls-cert", args.tls_cert), ("--tls-key", args.tls_key))
             if v is not None]
    if args.scheduler is None:
        if given or args.insecure_scheduler:
            raise UsageError(f"{(given or ['--insecure-scheduler'])[0]} needs --scheduler")
        return None
    if given and len(given) < 3:
        missing = [f for f in ("--tls-ca", "--tls-cert", "--tls-key") if f not in given]
        raise UsageError(f"{given[0]} needs {' and '.join(missing)} as well")
    tls = (args.tls_ca, args.tls_cert, args.tls_key) if given else None
    return check_scheduler(args.scheduler, tls, args.insecure_scheduler)
