"""python -m roadx_ti: run | eval | info | synth | bench | accuracy.

Exit codes: 0 ok, 2 usage or config error, 1 data error. User mistakes get one line on stderr,
never a traceback.
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import logging
import math
import os
import sys
import time
import warnings
from pathlib import Path


from roadx_ti import __version__, jsonio, units
from roadx_ti.config import parse_point_count
from roadx_ti.errors import DataError  # a data mistake: exit 1
from roadx_ti.memory import LIMIT_VARIABLE
from roadx_ti.result_dims import DECIDED_BY, RESULT_DIMS, result_dims

EXIT_OK, EXIT_DATA, EXIT_USAGE = 0, 1, 2
log = logging.getLogger("roadx_ti")
# the per-point results every run writes beside the classification (cmd_run's io.write): name -> dtype


class UsageError(Exception):
    """A usage mistake (exit 2)."""


class _OneLineParser(argparse.ArgumentParser):
    """argparse, whose mistakes are one line (its usage text is for --help); an option that takes
    one value is given once (_Once: argparse kept the last of two silently)."""

    def add_argument(self, *names, **kwargs):
        if names and names[0].startswith("-") and "action" not in kwargs and "nargs" not in kwargs:
            kwargs["action"] = _Once
        return super().add_argument(*names, **kwargs)

    def error(self, message):
        command = self.prog.partition(" ")[2]        # 'roadx_ti synth' -> 'synth'
        where = f"{command}: " if command else ""
        self.exit(EXIT_USAGE, f"roadx_ti: {where}{message} (see {self.prog} --help)\n")


class _Once(argparse.Action):
    """An option that takes one value: given twice, a usage error (argparse kept the last silently:
    '--output a.laz --output b.laz' wrote b.laz alone)."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given_once", set())    # (defaults are not "given")
        if self.dest in given:
            parser.error(f"{option_string} given twice; give it once")
        given.add(self.dest)
        setattr(namespace, self.dest, values)


def _parser() -> argparse.ArgumentParser:
    p = _OneLineParser(prog="roadx_ti", description=__doc__.split("\n")[0])
    p.add_argument("--version", action="version", version=f"roadx_ti {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_OneLineParser)

    r = sub.add_parser("run", help="run a pipeline from a YAML config")
    r.add_argument("config", help="YAML config (see configs/)")
    r.add_argument("--input", nargs="+", action="extend", metavar="PATH", help="input point cloud(s), folder(s) "
                   "or quoted wildcard patterns ('tiles/*.laz'), replacing the config's (repeatable)")
    r.add_argument("--output", metavar="PATH", help="output point cloud, replacing the config's")
    r.add_argument("--backend", choices=["auto", "cpu", "vulkan", "cuda", "metal"])
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set stages.sor.k=30 (repeatable)")
    r.add_argument("--quiet", action="store_true", help="only warnings and errors")
    r.add_argument("--workers", type=int, metavar="N", help="tiles on a local Dask cluster of N processes")
    r.add_argument("--scheduler", metavar="ADDRESS", help="tiles on an existing Dask scheduler, tcp://HOST:PORT")
    r.add_argument("--tile-size", type=float, metavar="M", help="core tile edge in metres (inf: untiled)")
    r.add_argument("--buffer", type=float, metavar="M", help="tile buffer in metres")
    r.add_argument("--output-mode", choices=["merged", "per-file"], help="tiled runs: merged or per-file output")
    r.add_argument("--memory-limit", metavar="SIZE", help="memory the run may use in total, e.g. 8G "
                   "(default: what the machine has available); runs that would need more stop, or run "
                   "in tiles with --set tiling.auto=true")

    e = sub.add_parser("eval", help="score a prediction against truth (matched by point order)")
    e.add_argument("--pred", required=True, metavar="PRED")
    e.add_argument("--truth", required=True, metavar="TRUTH")
    e.add_argument("--truth-classes", required=True, metavar="C[,C..]")
    e.add_argument("--pred-classes", metavar="C[,C..]", help="default: the truth classes")

    i = sub.add_parser("info", help="CRS, point count, bounds, density and spacing, colour / intensity / "
                       "NIR / returns, classes (JSON; --text for a person)")
    i.add_argument("path", nargs="+", help="file(s), folder(s) (their point-cloud files, as a catalog "
                   "takes them) or quoted wildcard patterns; several files: a JSON list")
    i.add_argument("--text", action="store_true", help="print for a person instead of JSON")

    s = sub.add_parser("synth", help="write a synthetic scene with truth classes")
    s.add_argument("--kind", required=True, choices=["uav-road", "uav-road-v1", "als-roof", "als-roof-v1"])
    s.add_argument("--points", required=True, type=parse_point_count)
    s.add_argument("--seed", type=_seed, default=0)
    s.add_argument("--density", type=_positive_density, default=None, metavar="POINTS_PER_M2",
                   help="points per m2 of the scene (its side follows; default: the kind's own)")
    s.add_argument("-o", "--output", required=True)
    b = sub.add_parser("bench", help="benchmarks: kernels and pipelines against their anchors")
    from roadx_ti import bench
    bench.add_arguments(b)

    a = sub.add_parser("accuracy", help="accuracy report of both pipelines on real and synthetic data")
    from roadx_ti import accuracy
    accuracy.add_arguments(a)
    return p



def _seed(text: str) -> int:
    """argparse type of --seed: an integer >= 0, as config seeds are."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a seed: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"seed must be >= 0, got {value}")
    return value


def _positive_density(text: str) -> float:
    """argparse type of synth --density: a finite number of points per m2 > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a density: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"density must be > 0 points per m2, got {text}")
    return value


def _classes(text: str, flag: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"{flag} {text!r}: expected class numbers like 11 or 2,11") from None
    if not values:
        raise UsageError(f"{flag} {text!r}: names no class; give class numbers like 11 or 2,11")
    if any(not 0 <= v <= 255 for v in values):
        raise UsageError(f"{flag} {text!r}: classes are integers 0..255")
    return values


def _setup_logging(quiet: bool) -> None:
    from roadx_ti.quiet_logs import say_as_the_cli

    say_as_the_cli(logging.WARNING if quiet else logging.INFO)
    # libraries' own log lines (laspy on odd headers) would add lines of their own to a one-line
    # message; what matters in them reaches the user through our messages
    for name in ("laspy", "lazrs"):
        library = logging.getLogger(name)
        library.handlers[:] = [logging.NullHandler()]
        library.propagate = False


RESULT_COMMANDS = ("eval", "info")      # the commands whose results are their standard output


def main(argv: list[str] | None = None) -> int:
    if sys.stderr is None:
        # '2>&-': the logs have nowhere to go, the run goes on (a write to None failed after the work)
        sys.stderr = open(os.devnull, "w")
    if sys.stdout is None:
        if argv is None and len(sys.argv) > 1 and sys.argv[1] in RESULT_COMMANDS:
            print(f"roadx_ti: {sys.argv[1]}: standard output is closed; its results would be lost", file=sys.stderr)
            return EXIT_USAGE
        sys.stdout = open(os.devnull, "w")
    for stream in (sys.stdout, sys.stderr):
        # a name the terminal's encoding cannot show (PYTHONIOENCODING=ascii, a non-UTF-8 locale) is
        # escaped, not an 'unexpected error: UnicodeEncodeError' after the work was done
        with contextlib.suppress(AttributeError, ValueError):
            stream.reconfigure(errors="backslashreplace")
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    _setup_logging(getattr(args, "quiet", False))
    from roadx_ti.backend import BackendError
    from roadx_ti.config import ConfigError
    from roadx_ti.io import InputError

    previous = _terminate_like_interrupt()
    # a config's memory_limit reaches local Dask workers through the environment: this run's only
    # (a second main() in the process, an embedding host's or a test's, ran under the first's limit)
    limit_before = os.environ.get(LIMIT_VARIABLE)
    from roadx_ti.io.atomic import RENAMED
    RENAMED.clear()          # main() may run more than once in a process (tests, embedding)
    if "roadx_ti.io.las" in sys.modules:     # (not imported for it: a refused run stays light)
        sys.modules["roadx_ti.io.las"].forget_warnings()
    try:
        with warnings.catch_warnings():
            # numpy's RuntimeWarning / UserWarning on absurd values (a header offset of 1e308, an
            # empty text table) would print lines of their own: the data checks report them
            warnings.simplefilter("ignore", RuntimeWarning)
            warnings.simplefilter("ignore", UserWarning)
            return {"run": cmd_run, "eval": cmd_eval, "info": cmd_info, "synth": cmd_synth,
                    "accuracy": cmd_accuracy, "bench": cmd_bench}[args.command](args)
    except (ConfigError, UsageError, BackendError) as exc:   # BackendError: --backend not on this machine
        print(f"roadx_ti: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except (InputError, DataError) as exc:
        if _RECEIVED:          # a signal raised inside a compressor's write, which took it for a failed write
            return _stopped_by(_RECEIVED[0])
        print(f"roadx_ti: {exc}", file=sys.stderr)
        return EXIT_DATA
    except BrokenPipeError:
        # `roadx_ti info x | head`: the reader left; not an error of ours
        sys.stderr.close()
        return EXIT_OK
    except Terminated as exc:
        print(f"roadx_ti: stopped by {exc.name}; {_left_behind()}", file=sys.stderr)
        return 128 + exc.number
    except KeyboardInterrupt:
        print(f"roadx_ti: interrupted; {_left_behind()}", file=sys.stderr)
        return 130
    except MemoryError:
        print("roadx_ti: out of memory; run in tiles (--tile-size) or on fewer points", file=sys.stderr)
        return EXIT_DATA
    except Exception as exc:   # a case nobody foresaw: one line (ROADX_TI_TRACEBACK=1 shows where)
        if _RECEIVED:          # a signal raised inside a library callback, which wrapped it
            return _stopped_by(_RECEIVED[0])
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            # a full disk or quota (the outputs' own writes say which file; this is e.g. stdout)
            print(f"roadx_ti: {(exc.strerror or 'no space left').lower()}"
                  f"{f' ({shown_path(exc.filename)})' if exc.filename else ''}", file=sys.stderr)
            return EXIT_DATA
        if isinstance(exc, OSError) and exc.errno in PATH_ERRNOS:
            # a path the system cannot take (a name over 255 bytes, a path over 4 KB, a loop of
            # links), from wherever it was first looked at: the user's mistake
            name = shown_path(exc.filename)
            print(f"roadx_ti: {name}: {(exc.strerror or 'bad path').lower()}; use a shorter path", file=sys.stderr)
            return EXIT_USAGE
        if os.environ.get("ROADX_TI_TRACEBACK"):
            raise
        text = " ".join(str(exc).split())[:300] or "(no message)"
        print(f"roadx_ti: unexpected error: {type(exc).__name__}: {text} "
              "(set ROADX_TI_TRACEBACK=1 for the traceback, and please report it)", file=sys.stderr)
        return EXIT_DATA
    finally:
        _restore_signals(previous)
        if limit_before is None:
            os.environ.pop(LIMIT_VARIABLE, None)
        else:
            os.environ[LIMIT_VARIABLE] = limit_before


_RECEIVED: list = []     # termination signals received during this main()
PATH_ERRNOS = {errno.ENAMETOOLONG, errno.ELOOP}


def shown_path(path, most: int = 80) -> str:
    """A path for a message: its first and last characters when it is long."""
    text = os.fsdecode(path) if path is not None else "a path"
    return text if len(text) <= most else f"{text[:most // 2 - 2]}...{text[-(most // 2 - 2):]}"


def _stopped_by(number: int) -> int:
    print(f"roadx_ti: stopped by {Terminated(number).name}; {_left_behind()}", file=sys.stderr)
    return 128 + number


def _left_behind() -> str:
    """What a stopped run leaves: no partial file, and the outputs it completed before the signal
    (a signal held while a run's files were renamed arrives after them: they are the new ones)."""
    from roadx_ti.io.atomic import RENAMED

    _quiet_shutdown()

    if not RENAMED:
        return "no partial output was left"
    more = f" and {len(RENAMED) - 1} more" if len(RENAMED) > 1 else ""
    return f"no partial output was left; complete before it: {RENAMED[-1]}{more}"


def _quiet_shutdown() -> None:
    """After a stop, the process's own shutdown says nothing more: a Dask cluster stopped while it
    started printed tracebacks after our one line (distributed's atexit close of a cluster still in
    its init state, tornado's log of the cancelled connection)."""
    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    sys.unraisablehook = lambda unraisable: None


class Terminated(BaseException):
    """SIGTERM / SIGHUP received: unwinds like Ctrl-C, so temporary files are removed."""

    def __init__(self, number: int):
        import signal

        super().__init__(number)
        self.number = number
        self.name = signal.Signals(number).name


def _terminate_like_interrupt() -> dict:
    """SIGTERM and SIGHUP raise Terminated, SIGINT KeyboardInterrupt, and each is remembered (a
    library that calls back into Python may wrap the exception: main() still reports the signal);
    main thread only; returns the previous handlers. A run stopped by a batch scheduler or a
    closed terminal unwinds and removes its temporary files instead of dying with them."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}

    def handler(number, frame):
        _RECEIVED.append(number)
        if number == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(number)

    previous = {}
    _RECEIVED.clear()
    for name in ("SIGTERM", "SIGHUP", "SIGINT"):
        number = getattr(signal, name, None)
        if number is not None:
            previous[number] = signal.signal(number, handler)
    return previous


def _restore_signals(previous: dict) -> None:
    import signal

    for number, handler in previous.items():
        signal.signal(number, handler)


# --------------------------------------------------------------------------------------- run
def _output_paths(out: Path) -> dict:
    from roadx_ti.config import output_stem

    stem = output_stem(out)
    return {"summary": Path(f"{stem}.summary.json"), "config": Path(f"{stem}.config.yaml"),
            "png": Path(f"{stem}.png")}


def _sidecars_written(cfg, out: Path) -> dict:
    """The files besides the point cloud that the run writes (kind: path)."""
    if cfg.tiled and cfg.output.mode == "per-file":
        return {"summary": out / "summary.json", "config": out / "config.yaml"}
    written = _output_paths(out)
    if cfg.dtm_path() is not None:
        written.update(_dtm_files(cfg.dtm_path()))
    return written


def _dtm_files(dtm: Path) -> dict:
    """The DTM and the files a DTM writer puts beside it (x.json of x.npy, x.prj of x.asc)."""
    return {"DTM": dtm, "DTM placement": dtm.with_suffix(".json"), "DTM projection": dtm.with_suffix(".prj")}


def _refuse_writing_over(cfg, out: Path, config_path) -> None:
    """A sidecar of the run must not be the config file it runs or one of its inputs (a config named
    k.config.yaml beside --output k.laz was replaced by the resolved copy, its comments lost)."""
    from roadx_ti.io.atomic import same_file

    protected = [("the config file it runs", config_path)] + [("its input", p) for p in cfg.input.paths]
    for kind, path in _sidecars_written(cfg, out).items():
        for what, other in protected:
            if same_file(path, other):
                raise UsageError(f"{path}: the run writes its {kind} file there, over {what}; choose another "
                                 "output name (or move the file)")


def _warn_stale_sidecars(cfg, out: Path) -> None:
    """An earlier run's picture or DTM beside the output that this run does not write again (the
    picture off, a tiled run, no DTM) would sit beside results it does not show: say so."""
    if cfg.tiled and cfg.output.mode == "per-file":
        return
    from roadx_ti.config import output_stem

    left = []
    if not cfg.output.report_png or cfg.tiled:
        left.append(_output_paths(out)["png"])
    if cfg.dtm_path() is None:
        left.append(Path(f"{output_stem(out)}.dtm.tif"))     # config.dtm_path's default
    for path in left:
        if path.is_file():
            log.warning("%s: an earlier run's file, which this run does not write again; it does not show this "
                        "run's result (remove it)", path)


def _check_distinct_outputs(out: Path, dtm: Path) -> None:
    """The DTM and its sidecars (x.json of x.npy, x.prj of x.asc) must not be the run's other files:
    output.dtm=r.summary.npy would write the DTM's placement over the run's summary."""
    from roadx_ti.io.atomic import same_file

    mine = {"output": out, **_output_paths(out)}
    for name, path in mine.items():
        for other in _dtm_files(dtm).values():
            if same_file(path, other):
                raise UsageError(f"output.dtm = {dtm}: its file {other} would be the run's {name} file; "
                                 "give the DTM another name")


def cmd_run(args) -> int:
    from roadx_ti.io.atomic import output_group

    # the run's outputs (cloud, summary, config, DTM, picture) replace earlier ones together or not at
    # all, and the folders made for them go again when the run fails
    with _removing_made_folders(), output_group():
        return _cmd_run(args)


# output folders this command made (deepest last), removed again when it fails while they are empty
_MADE_FOLDERS: list = []


@contextlib.contextmanager
def _removing_made_folders():
    """Inside, the output folders _mkdir makes are noted; when the command fails they go again
    where they are empty."""
    _MADE_FOLDERS.clear()
    try:
        yield
    except BaseException:
        for folder in reversed(_MADE_FOLDERS):
            with contextlib.suppress(OSError):
                folder.rmdir()               # only an empty folder goes
        raise
    finally:
        _MADE_FOLDERS.clear()


def _mkdir(folder: Path) -> None:
    """``folder.mkdir(parents=True, exist_ok=True)``, noting the folders it makes (_MADE_FOLDERS)."""
    missing = []
    at = Path(folder)
    while not at.exists() and at != at.parent:
        missing.append(at)
        at = at.parent
    folder.mkdir(parents=True, exist_ok=True)
    _MADE_FOLDERS.extend(reversed(missing))


def _cmd_run(args) -> int:
    from roadx_ti import backend, config, io, pipelines
    from roadx_ti.stages.base import GROUND_SURFACE, StageContext

    overrides = list(args.set)
    for flag, key in (("workers", "executor.workers"), ("scheduler", "executor.scheduler"),
                      ("tile_size", "tiling.tile_size"), ("buffer", "tiling.buffer"),
                      ("output_mode", "output.mode"), ("memory_limit", "memory_limit")):
        value = getattr(args, flag)
        if isinstance(value, float) and not math.isfinite(value):
            value = ".nan" if math.isnan(value) else ("-.inf" if value < 0 else ".inf")   # YAML's spellings
        if value is not None:
            overrides.append(f"{key}={value}")
    cfg = config.load(args.config, overrides)
    if args.input:
        cfg.input = config.InputConfig(paths=list(args.input))
    if args.output is not None:
        why = config.output_name_problem(args.output)
        if why:
            raise UsageError(f"--output: {why}")
        cfg.output.path = args.output
    if args.backend:
        cfg.backend = args.backend
    if args.buffer is not None and not cfg.tiled:
        log.warning("--buffer is the tiles' buffer; this run is untiled (give --tile-size to tile it)")
    if not cfg.input.paths and cfg.input.synthetic is None:
        raise config.ConfigError("config error: input: give input.paths, input.synthetic or --input PATH")
    cfg.input.paths = _expand_patterns(cfg.input.paths)
    # after the patterns are expanded: 'tiles/*.laz' is a catalog
    if cfg.output.mode == "per-file" and not cfg.tiled and Path(str(cfg.output.path)).suffix.lower() not in io.EXTENSIONS:
        # (it said "unknown output format '(no extension)'" of the folder it was given)
        raise UsageError(f"{cfg.output.path}: output.mode per-file writes one file per input of a catalog or tiled "
                         "run into a folder; this run is one file, untiled: give an output file name (e.g. out.laz)")
    out = Path(cfg.output.path)
    if cfg.dtm_path() is not None:
        _check_distinct_outputs(out, cfg.dtm_path())
    _refuse_writing_over(cfg, out, args.config)
    _warn_stale_sidecars(cfg, out)
    from roadx_ti import memory
    if cfg.memory_limit:
        os.environ[memory.LIMIT_VARIABLE] = cfg.memory_limit     # also seen by local Dask workers
    if not cfg.tiled:
        memory.check_run(cfg, memory.points_before_reading(cfg))
    if cfg.tiled:
        return _run_tiled(cfg, out, args)
    _prepare_output(out, cfg.input.paths)
    if cfg.dtm_path() is not None:
        _make_parent(cfg.dtm_path())
        io.check_output_path(cfg.dtm_path(), cfg.input.paths)
    stage_specs = cfg.pipeline_stages()     # the option objects config validation built

    t0 = time.perf_counter()
    if cfg.input.synthetic is not None and not cfg.input.paths:
        from roadx_ti import synthetic
        s = cfg.input.synthetic
        cloud = synthetic.generate(s.kind, s.points, s.seed)
    else:
        # LAS/LAZ into LAS/LAZ: the records are not held through the run; the writer streams them
        # from the input again (every attribute bit for bit, 36 B per point of format 7 less held)
        cloud = io.read(cfg.input.paths[0], keep_records=not _streams_records(cfg.input.paths[0], out))
    read_s = time.perf_counter() - t0
    log.info("read %d points from %s in %.2f s", cloud.n, cloud.source, read_s)
    if cloud.n == 0:
        raise DataError(f"{cloud.source}: the input holds no points")
    if cloud.las is None and not cloud.records_file and out.suffix.lower() in (".las", ".laz"):
        from roadx_ti.io.las_write import fits_new_file
        if not fits_new_file(cloud.xyz):     # say it now, not after the whole pipeline
            raise DataError(f"{out}: the points of {cloud.source} span more than +-2147 km from their origin, "
                            "which a LAS file at 1 mm scale cannot hold; split the cloud or write .ply/.npz")
    if memory.points_before_reading(cfg) is None:   # formats without a header count: now it is known
        memory.check_run(cfg, cloud.n, cloud)
        if cfg.tiled:
            del cloud
            return _run_tiled(cfg, out, args)
    # columns the output format cannot hold: say it now, not after the whole pipeline
    from roadx_ti.stages import stage_class
    written = dict(RESULT_DIMS)                 # and each stage's own data (float32)
    written.update({name: "float32" for stage, _ in stage_specs for name in stage_class(stage).writes})
    io.check_writable(out, cloud, written)
    if cfg.input.paths:
        from roadx_ti.io.las_write import check_writable_records_of
        check_writable_records_of(out, cfg.input.paths[0])

    from roadx_ti.io import crs as io_crs
    crs = io_crs.of_cloud(cloud)
    factors = _survey_units(cloud, crs)
    work = units.in_metres(cloud, factors)

    arch = backend.init(cfg.backend, threads=cfg.threads)
    log.info("Taichi backend: %s", arch)
    truth = None
    if cloud.classification is not None:
        from roadx_ti.metrics import class_mask, no_truth_line
        truth = class_mask(cloud.classification, cfg.truth_classes)
        if not truth.any():
            truth = None
            log.info(no_truth_line(cfg.truth_classes))
    ctx = StageContext(seed=cfg.seed, log=log)
    stages = pipelines.build_stages(stage_specs)
    progress = _progress_bar(len(stages), args.quiet)
    result = pipelines.run(work, stages, ctx=ctx, truth=truth, progress=progress)
    if progress is not None:
        progress.close()
    del work
    for name in units.LENGTH_DIMS:
        if name in result.extra_dims and not factors.metric:
            result.extra_dims[name] = (result.extra_dims[name] / factors.vertical).astype("float32")

    target = config.PIPELINE_TARGET[cfg.pipeline]
    subset = None if cfg.output.points == "all" else result.processed
    t1 = time.perf_counter()
    io.write(out, cloud, classification=result.classification,
             extra_dims=result_dims(result.decided_by, result.segment_id, result.extra_dims),
             subset=subset)
    write_s = time.perf_counter() - t1
    paths = _output_paths(out)
    summary = {
        "roadx_ti": __version__, "pipeline": cfg.pipeline, "input": cloud.source, "output": str(out),
        "points": cloud.n, "backend": arch, "read_seconds": round(read_s, 4),
        "pipeline_seconds": round(result.seconds, 4), "write_seconds": round(write_s, 4),
        "target_class": target, "target_points": int((result.classification == target).sum()),
        DECIDED_BY: {"0": "reached the last stage"} | {str(r["index"]): f"removed by {r['stage']}"
                                                         for r in result.stages},
        "estimates": result.estimates,
        "stages": result.stages,
    }
    if result.repeated:
        summary["repeated_points"] = result.repeated     # records at another's x, y, z: its labels
    if not factors.metric:
        summary["units"] = {"input": factors.name, "metres_per_unit": {"horizontal": factors.horizontal,
                                                                        "vertical": factors.vertical},
                            "note": "stages ran in metres: estimates and stage figures are metres"}
    if truth is not None:
        from roadx_ti.metrics import scores
        summary["truth_classes"] = cfg.truth_classes
        summary["accuracy"] = scores(truth, result.classification == target)
        acc = summary["accuracy"]
        log.info("accuracy vs classes %s: type I %.2f %%, type II %.2f %%, total %.2f %%, kappa %.4f",
                 cfg.truth_classes, 100 * acc["type1"], 100 * acc["type2"], 100 * acc["total"], acc["kappa"])
    dtm_path = cfg.dtm_path()
    if dtm_path is not None:
        surface = ctx.facts.get(GROUND_SURFACE)
        if surface is None:
            if cfg.output.dtm is not None:
                log.warning("output.dtm: no ground stage ran, so there is no DTM to write")
        else:
            if len(surface.parts) > 1:
                log.warning("output.dtm: the cloud is %d parts more than 100 m apart; the DTM covers the "
                            "largest (a raster over all would be sized by the gaps)", len(surface.parts))
            summary["dtm"] = _write_dtm(dtm_path, units.surface_in_units(surface, factors), cloud, crs)
    from roadx_ti import report
    jsonio.write(paths["summary"], summary)
    with io.atomic_output(paths["config"]) as tmp:
        Path(tmp).write_text(config.dump(cfg))
    if cfg.output.report_png:
        report.top_view_png(paths["png"], cloud, result.classification == target, truth=truth,
                            target=cfg.pipeline,
                            title=f"{cfg.pipeline} pipeline: {_scene_name(cfg, cloud)}")
    log.info("wrote %s (+ %s, %s%s) in %.2f s total", out, paths["summary"].name, paths["config"].name,
             f", {paths['png'].name}" if cfg.output.report_png else "", time.perf_counter() - t0)
    return EXIT_OK


def _survey_units(cloud, crs):
    """The metres per unit of the cloud's CRS ``crs`` (roadx_ti.units), logged when not metres; a
    cloud in longitude / latitude degrees stops the run with one line."""
    if crs is not None and crs.is_geographic and cloud.n:
        import numpy as np
        reach = np.abs(cloud.xyz[:, :2].astype(np.float64) + cloud.origin[:2]).max(axis=0)
        raise DataError(f"{cloud.source}: {units.geographic_problem(crs, float(reach[0]), float(reach[1]))}")
    if crs is None and units.looks_like_degrees(cloud):
        log.warning("%s: no CRS in the file, and x / y read as longitude / latitude degrees (the stages' lengths "
                    "are metres: every spacing would read 0); if so, reproject it to a projected CRS first",
                    cloud.source)
    factors = units.metre_factors(crs)
    if not factors.metric:
        log.info("%s counts in %s (%.10g m; heights %.10g m per unit): the stages run in metres, the "
                 "output keeps the file's coordinates", cloud.source, factors.name, factors.horizontal,
                 factors.vertical)
    return factors


def _streams_records(source, out: Path) -> bool:
    """True when the run's LAS/LAZ output can stream the records of its LAS/LAZ input from the
    file (COPC output orders its points itself and takes them all in memory)."""
    from roadx_ti.io import copc
    las = (".las", ".laz")
    return Path(source).suffix.lower() in las and out.suffix.lower() in las and not copc.is_copc_path(out)


def _scene_name(cfg, cloud) -> str:
    if cloud.las is not None or cfg.input.paths:
        return Path(cloud.source).name
    s = cfg.input.synthetic
    return f"synthetic {s.kind} scene, {s.points:,} points, seed {s.seed}"


def _write_dtm(path: Path, surface, cloud, crs) -> dict:
    """The ground surface (stages.base.GroundSurface) as a DTM raster over the occupied space, with
    the input's CRS ``crs`` (rasterio CRS or None)."""
    from roadx_ti import dtm

    t = dtm.write(path, surface.largest, surface.origin, xy=cloud.xyz[:, :2], crs=crs)
    if t is None:
        log.warning("output.dtm: no cell of the ground surface lies under the points; no DTM written")
        return {"path": None, "reason": "no cell of the ground surface lies under the points"}
    log.info("wrote DTM %s: %d x %d cells of %g m over the occupied area (%d with data)", path,
             t["cols"], t["rows"], t["cell_size"], t["valid_cells"])
    return dtm.summary(path, t, crs)


def _prepare_output(out: Path, inputs) -> None:
    """Refuse a bad output before any work: an unknown format, an input, an impossible folder."""
    from roadx_ti import io
    from roadx_ti.io.atomic import refuse_folder

    refuse_folder(out)      # before the format test: a folder has no extension to complain of
    if out.suffix.lower() not in io.EXTENSIONS:
        raise UsageError(f"{out}: unknown output format {out.suffix or '(no extension)'!r}; "
                         f"use one of {' '.join(io.EXTENSIONS)}")
    _check_copc(out)
    _make_parent(out)
    io.check_output_path(out, inputs)
    for kind, sidecar in _output_paths(out).items():   # a folder in a sidecar's place: say it now
        if sidecar.is_dir():
            raise io.InputError(f"{sidecar}: is a folder where the run writes its {kind} file; move it, or choose "
                                "another output name")


def _check_copc(out: Path) -> None:
    from roadx_ti.io import copc

    if copc.is_copc_path(out) and copc.missing():
        raise UsageError(f"{out}: {copc.missing()}")


def _run_tiled(cfg, out: Path, args) -> int:
    from roadx_ti import config, io, tiling

    if not cfg.input.paths:
        raise config.ConfigError("config error: input: tiled runs read files; give input.paths or --input")
    from roadx_ti.tiling.run import dtm_output
    inputs = [f.path for f in tiling.catalog(cfg.input.paths, warn=False)]
    from roadx_ti.io.las_write import check_writable_records_of
    merged = {}
    for path in inputs:     # before the tiles, not at the merge (decodes only formats 9 / 10 into LAZ)
        check_writable_records_of(out if cfg.output.mode == "merged" else out / Path(path).name, path,
                                  merged if cfg.output.mode == "merged" else None)
    if cfg.output.report_png:
        # the echoed config says report_png: true; the picture is drawn from one cloud in memory
        log.info("tiled runs write no picture (output.report_png applies to untiled runs)")
    dtm_path = dtm_output(cfg, out, cfg.output.mode)
    if dtm_path is not None and (cfg.output.mode != "per-file" or isinstance(cfg.output.dtm, str)):
        # (per-file's own dtm.tif goes into the output folder, made below)
        _make_parent(dtm_path)
        io.check_output_path(dtm_path, inputs)
    if cfg.output.mode == "merged":
        from roadx_ti.io.copc import is_copc_path
        if is_copc_path(out):
            raise UsageError(f"{out}: tiled runs write LAS/LAZ, not COPC yet (COPC needs all points at "
                             "once); write .laz and convert it, e.g. pdal translate x.laz x.copc.laz")
        _make_parent(out)
        io.check_output_path(out, inputs)
    else:
        if out.suffix.lower() in io.EXTENSIONS and not out.is_dir():
            # one file per input goes into a folder: a name like x.laz was meant as a file
            raise UsageError(f"{out}: output.mode per-file writes one file per input into a folder; "
                             "give a folder (e.g. --output out/) or use output.mode merged for one file")
        make_output_folder(out, "output.mode per-file writes one file per input into a folder", DataError)
    try:
        summary = tiling.run_catalog(cfg, cfg.input.paths, out, workers=cfg.executor.workers,
                                     scheduler=cfg.executor.scheduler, tile_size=cfg.tiling.tile_size,
                                     buffer=cfg.tiling.buffer, output_mode=cfg.output.mode,
                                     progress=not args.quiet, log=log)
    except tiling.TileError as exc:
        raise DataError(str(exc)) from None
    except ValueError as exc:
        if isinstance(exc, io.InputError):
            raise
        raise UsageError(str(exc)) from None
    config_path = (out / "config.yaml") if cfg.output.mode == "per-file" else _output_paths(out)["config"]
    with io.atomic_output(config_path) as tmp:
        Path(tmp).write_text(config.dump(cfg))
    log.info("tiled run: %d tiles, %d points written", len(summary.get("tiles", [])),
             summary.get("points_written", 0))
    if summary.get("accuracy"):
        acc = summary["accuracy"]       # as the untiled run says it
        log.info("accuracy vs classes %s: type I %s, type II %s, total %s, kappa %s", summary.get("truth_classes"),
                 *(("-" if acc.get(k) is None else f"{100 * acc[k]:.2f} %") for k in ("type1", "type2", "total")),
                 "-" if acc.get("kappa") is None else f"{acc['kappa']:.4f}")
    return EXIT_OK


def make_output_folder(folder: Path, purpose: str, error=UsageError) -> None:
    """Create the output folder ``folder`` (its parents too), or say in one line why not: it is a
    file (a usage error naming ``purpose``), or it cannot be made or written in (``error``)."""
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{folder}: is a file; {purpose}")
    try:
        _mkdir(folder)
    except OSError as exc:
        raise error(f"{folder}: cannot create the output folder ({exc.strerror or exc})") from None
    if not os.access(folder, os.W_OK):
        raise error(f"{folder}: cannot write in the output folder")


def _make_parent(out: Path) -> None:
    """Create the output's folder, as users of PDAL and friends expect; failures are data errors."""
    try:
        _mkdir(out.parent)
    except OSError as exc:
        raise DataError(f"{out}: cannot create the output folder: {exc.strerror}") from None


def _matches(pattern: str) -> list[str] | None:
    """The files a wildcard pattern (tiles/*.laz, as PDAL and shells take) matches, in sorted
    order; None when ``pattern`` is an existing path or holds no wildcard."""
    import glob

    if Path(pattern).exists() or not glob.has_magic(pattern):
        return None
    # '**' any depth of folders, as PDAL's and the shells' globstar take it (it matched one level)
    return sorted(m for m in glob.glob(pattern, recursive=True) if Path(m).is_file())


def _expand_patterns(paths: list[str]) -> list[str]:
    """Input paths as given, a wildcard pattern replaced by the files it matches; a path that is
    neither, or a pattern that matches nothing, is a one-line config error."""
    from roadx_ti.config import ConfigError
    from roadx_ti.tiling.catalogs import pattern_files

    out = []
    for p in paths:
        matches = _matches(p)
        if matches is None and not Path(p).exists():
            if p == "-":
                raise ConfigError("config error: input.paths = '-': reading points from standard input is "
                                  "not supported; give a file, a folder or a wildcard pattern")
            raise ConfigError(f"config error: input.paths = {p!r}: no such file")
        if matches == []:
            raise ConfigError(f"config error: input.paths = {p!r}: no file matches the pattern")
        out.extend([p] if matches is None else [str(q) for q in pattern_files(p, matches)])
    return out


def _progress_bar(total: int, quiet: bool):
    if quiet or not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    bar = tqdm(total=total, unit="stage", file=sys.stderr, leave=False)

    def advance(name, number, count):
        bar.set_description(name)
        bar.update(1)
    advance.close = bar.close
    return advance


# -------------------------------------------------------------------------------------- eval
def cmd_eval(args) -> int:
    from roadx_ti import io
    from roadx_ti.metrics import class_mask, scores

    truth_classes = _classes(args.truth_classes, "--truth-classes")
    pred_classes = _classes(args.pred_classes, "--pred-classes") if args.pred_classes is not None else truth_classes
    for given, flag in ((args.pred, "--pred"), (args.truth, "--truth")):
        if not Path(given).exists():
            import glob
            if glob.has_magic(given):
                raise UsageError(f"{flag} {given}: a pattern; eval compares two files point by point (give one file)")
            raise UsageError(f"{flag} {given}: no such file")
        if Path(given).is_dir():
            raise UsageError(f"{flag} {given}: is a folder; eval compares two files point by point")
    pred = io.read(args.pred)
    truth = io.read(args.truth)
    if pred.n != truth.n:
        raise DataError(f"{args.pred} has {pred.n} points but {args.truth} has {truth.n}: "
                        "points are matched by order, the counts must be equal")
    for cloud, name in ((pred, args.pred), (truth, args.truth)):
        if cloud.classification is None and "classification" in {k.lower() for k in cloud.attributes}:
            raise DataError(f"{name}: its classification column holds values that are not classes 0..255")
        if cloud.classification is None:
            raise DataError(f"{name} has no classification")
    _same_points(pred, truth, args.pred, args.truth)
    if not truth.n:
        log.warning("%s and %s hold no points; every measure is null", args.pred, args.truth)
    for cloud, classes, name in ((pred, pred_classes, args.pred), (truth, truth_classes, args.truth)):
        if cloud.n and not class_mask(cloud.classification, classes).any():
            log.warning("%s: no point carries class %s", name, ", ".join(str(c) for c in classes))
    result = scores(class_mask(truth.classification, truth_classes), class_mask(pred.classification, pred_classes))
    result["truth_classes"], result["pred_classes"] = truth_classes, pred_classes
    print(jsonio.dumps(result))
    return EXIT_OK


# m: points of the two files farther apart than this (beyond their coordinates' resolution) are
# not the same points
SAME_POINT_TOLERANCE = 0.01


def _same_points(pred, truth, pred_name, truth_name) -> None:
    """eval matches points by order: the two files' points must be where the other's are (a truth
    file of the same points in another order gave kappa near 0, silently)."""
    import numpy as np

    if not pred.n:
        return
    apart = np.abs(pred.world_xyz() - truth.world_xyz()).max(axis=1) > SAME_POINT_TOLERANCE + 1e-6
    if apart.any():
        i = int(np.flatnonzero(apart)[0])
        raise DataError(f"{pred_name} and {truth_name}: {int(apart.sum()):,} of {pred.n:,} points lie more than "
                        f"{SAME_POINT_TOLERANCE * 100:g} cm from their namesake (first: point {i}); eval matches "
                        "points by order, so both files must hold the same points in the same order")


# -------------------------------------------------------------------------------------- info
def cmd_info(args) -> int:
    from roadx_ti import io
    from roadx_ti.io import InputError

    from roadx_ti.io.describe import text
    from roadx_ti.tiling.catalogs import folder_files, pattern_files

    files = []
    for given in args.path:
        matches = _matches(given)
        if matches == []:
            raise UsageError(f"{given}: no file matches the pattern")
        if matches is None and not Path(given).exists():
            raise UsageError(f"{given}: no such file")
        for path in [given] if matches is None else pattern_files(given, matches):
            files.extend(folder_files(Path(path)) if Path(path).is_dir() else [path])
    infos, failed = [], []
    for f in files:
        try:
            infos.append(io.info(str(f)))
        except (InputError, DataError) as exc:
            if len(files) == 1:
                raise
            # a folder or pattern: every file is described, a bad one by its error (lasinfo goes on
            # too); it said the first bad file's error alone
            failed.append(str(exc))
            infos.append({"path": str(f), "error": str(exc)})
    if args.text:
        print("\n\n".join(text(info) for info in infos))
    else:
        print(jsonio.dumps(infos[0] if len(infos) == 1 else infos, indent=2))
    for message in failed:
        print(f"roadx_ti: {message}", file=sys.stderr)
    return EXIT_DATA if failed else EXIT_OK


# ---------------------------------------------------------------------------------- accuracy
def cmd_accuracy(args) -> int:
    from roadx_ti import accuracy

    with _removing_made_folders():      # the report's folder, made for a run that failed, when empty
        return accuracy.main(args)


def cmd_bench(args) -> int:
    from roadx_ti import bench

    return bench.main(args)


# ------------------------------------------------------------------------------------- synth
def cmd_synth(args) -> int:
    with _removing_made_folders():      # the output's folders, made for a scene that was refused
        return _cmd_synth(args)


def _cmd_synth(args) -> int:
    from roadx_ti import io, memory, synthetic

    out = Path(args.output)
    if isinstance(args.points, int) and args.points < synthetic.MIN_POINTS:
        raise UsageError(f"--points {args.points}: a synthetic scene has at least {synthetic.MIN_POINTS} points")
    _prepare_output(out, [])
    # a scene is made whole in memory: refuse one that cannot fit before laying it out (1e12
    # for 1e7 would otherwise lay out a city for minutes, then fail)
    ok, need, budget = memory.fits("synth", args.points)
    if not ok:
        raise UsageError(f"a synthetic scene of {args.points:,} points needs about "
                         f"{memory.format_size(need * memory.SAFETY)} of memory, more than the "
                         f"{memory.format_size(budget)} this run may use: write a smaller scene, or "
                         "several (other seeds) into one folder, which runs as a catalog")
    try:
        cloud = synthetic.generate(args.kind, args.points, args.seed, density=args.density)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    io.write(out, cloud, classification=cloud.classification)
    log.info("wrote %d points (%s, seed %d) to %s", cloud.n, args.kind, args.seed, out)
    return EXIT_OK
