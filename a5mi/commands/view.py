"""``a5mi view SCENE.txt [a5 flags] [--reference IMG | --binary PATH] [--port N] [--open] [--no-preview]``: the
live page.

Starts a local web server on 127.0.0.1 (a free port unless ``--port``) whose URL, with a one-time token, is
printed on stdout; the page (:mod:`a5mi.view`, docs/VIEW.md) shows the render, the reference, the heatmap and
``compare``'s verdict, re-renders when a control changes or a file the scene read is saved, traces a clicked
pixel, zooms the three images together, shows the values under the cursor, renders a region marked with
shift+drag first at full quality on each save (the crop render), and diagnoses the render or the reference
(docs/MISTAKES.md). One warm :class:`a5mi.render.session.RenderSession` renders everything on this (the
main) thread; the server and the file watcher run on their own threads. A closed tab does not stop it; Ctrl-C does
(exit 130).
"""

from __future__ import annotations

import secrets

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, Positional, integer, real, text
from a5mi.commands.render import FORCE_FLAG, IMAGE_OUTPUT_DESTS, check_render_args, render_flags_except, render_options
from a5mi.platform.errors import ExitStatus, UsageError

FLAGS: tuple[Flag, ...] = (
    *render_flags_except(IMAGE_OUTPUT_DESTS | {"input", "verbose"}),
    FORCE_FLAG,
    Flag(("--reference",), "reference", "compare with this image (the course's reference render)", 1, text,
         metavar="IMG"),
    Flag(("--binary",), "binary", "compare with this a5 executable's render of the same scene and SPEC B.1 flags, "
         "run sandboxed as a5mi difftest runs it", 1, text, metavar="PATH"),
    Flag(("--allow-read",), "allow_read", "with --binary: extra paths it may read (':'-separated)", 1, text,
         metavar="PATHS"),
    Flag(("--timeout",), "timeout", "with --binary: seconds one of its runs may take", 1, real, 60.0, "S"),
    Flag(("--port",), "port", "port on 127.0.0.1 (0: a free one)", 1, integer(0, 65535), 0, "N"),
    Flag(("--open",), "open", "open the page in the default browser", default=False, show_default=False),
    Flag(("--no-preview",), "no_preview", "never show the one-ray preview before a -jitter/-filter/-spp image (by "
         "default it shows when the last full image took over 0.5 s)", default=False, show_default=False),
)


def check_view_args(args: Args) -> None:
    check_render_args(args)
    if args.reference is not None and args.binary is not None:
        raise UsageError("give --reference IMG or --binary PATH, not both")
    if args.timeout <= 0:
        raise UsageError("--timeout must be positive")


def run_view(args: Args, console: Console) -> int:
    from a5mi.platform.imageio import check_image_fits
    from a5mi.sandbox import bwrap as sandbox

    binary = None
    if args.reference is not None:
        check_image_fits(args.reference)  # unreadable or not an image: one line now, not on the page
    if args.binary is not None:
        from a5mi.difftest.runner import Binary, check_binary

        why = sandbox.sandbox_problem()
        if why:
            raise UsageError(f"--binary: {why}: refusing to run an untrusted executable unsandboxed (install "
                             f"bubblewrap: {sandbox.INSTALL_HINT})")
        allow = tuple(p for p in (args.allow_read or "").split(":") if p)
        binary = Binary(check_binary(args.binary), allow)
    options = render_options(args, normals=False, depth=None, count_rays=False)
    return _serve(args, console, options, binary)


def _serve(args: Args, console: Console, options: object, binary: object) -> int:
    from a5mi.view import controls
    from a5mi.view.build import ViewSession
    from a5mi.view.engine import ViewEngine
    from a5mi.view.live import run_engine
    from a5mi.view.server import Hub, Jobs, Server
    from a5mi.view.watcher import Watcher

    hub, jobs = Hub(), Jobs()
    try:  # the port first: a port in use is one line before Mitsuba is loaded
        server = Server(secrets.token_urlsafe(24), hub, jobs, lambda values: controls.apply(options, values),
                        args.port)
    except OSError as exc:
        raise UsageError(f"cannot listen on 127.0.0.1:{args.port}: {exc.strerror or exc}") from None
    try:
        activate_variant(args.variant)
        session = ViewSession(args.variant)
    except BaseException:
        server.httpd.server_close()
        raise
    engine = ViewEngine(args.scene, session, reference=args.reference, binary=binary, timeout=args.timeout,
                        force=bool(args.get("force")))
    watcher = Watcher(lambda: jobs.render(reload=True))
    server.start()
    watcher.start()
    try:
        console.result(f"a5mi view: {server.url}")
        console.note("a5mi view: serving on 127.0.0.1 only; the page reloads when the scene's files change; "
                     "Ctrl-C stops")
        if args.open:
            import webbrowser

            webbrowser.open(server.url)
        run_engine(engine, hub, jobs, watcher, options, log=console.error, preview=not args.no_preview)
    finally:
        watcher.stop()
        server.stop()
        engine.close()
    return ExitStatus.OK


VIEW = Command("view", "Serve a live page on 127.0.0.1: the render, the reference and their heatmap and verdict, "
               "flag controls, re-render on save, the ray tree of a clicked pixel, zoom, the values under the cursor, "
               "exposure, an A/B flip, a marked region rendered first at full quality and a diagnose panel.",
               FLAGS, run_view, (Positional("scene", "SCENE.txt", "the scene to show"),), check=check_view_args,
               epilog="The URL printed carries a one-time token; every request without it is refused (403). "
               "docs/VIEW.md.", exit_ok="never: the server runs until it is stopped (Ctrl-C: 130)")
