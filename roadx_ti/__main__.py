import sys


def _interrupted(exc: BaseException) -> bool:
    """Ctrl-C inside an extension module's import surfaces as an ImportError around it."""
    while exc is not None:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


try:
    # Ctrl-C during the imports (a second or so) or before main's own handlers: one line too
    from roadx_ti.cli import main
    code = main()
except (KeyboardInterrupt, ImportError) as exc:
    if not _interrupted(exc):
        raise
    print("roadx_ti: interrupted; no output was written", file=sys.stderr)
    code = 130
raise SystemExit(code)
