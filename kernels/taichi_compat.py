"""The one import of Taichi, and every call that depends on which Taichi it is.

roadx_ti runs on Taichi 1.7.4 (``import taichi``; wheels up to Python 3.13) and on taichi-forge
(``import taichi_forge``; a maintained fork that keeps 1.7.4's API, wheels for Python 3.10-3.14).
Every module of the project takes ``ti`` from here, so the choice is made once per process:

- ``ROADX_TI_TAICHI=taichi`` or ``=taichi_forge`` asks for one (an error when it is not installed);
- otherwise (``auto``) ``taichi`` where it is installed, else ``taichi_forge``.

The two keep their runtimes apart: a host program that embeds roadx_ti and calls ``ti.init``
itself must use the same distribution (``DISTRIBUTION`` says which one roadx_ti took).
The internals read below (``ti.lang.impl``, ``ti.lang._ndarray``) are not public API in either,
which is why they live here and nowhere else; so are the three helpers of Taichi 1.7.4 that
``_quicker_kernel_transforms`` replaces by faster ones returning the same results.
"""
from __future__ import annotations

import importlib
import os
import sys

DISTRIBUTIONS = ("taichi", "taichi_forge")
ENVIRONMENT_VARIABLE = "ROADX_TI_TAICHI"


class TaichiImportError(ImportError):
    """Neither Taichi distribution can be imported (or the one asked for is missing)."""


def _import_taichi():
    wanted = os.environ.get(ENVIRONMENT_VARIABLE, "auto").strip().lower().replace("-", "_") or "auto"
    if wanted not in DISTRIBUTIONS + ("auto",):
        raise TaichiImportError(f"{ENVIRONMENT_VARIABLE}={wanted!r}: use one of auto, "
                                f"{', '.join(DISTRIBUTIONS)}")
    candidates = DISTRIBUTIONS if wanted == "auto" else (wanted,)
    for name in candidates:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:   # installed but broken: say so, do not hide it behind a fallback
                raise
    raise TaichiImportError(
        f"no Taichi found ({' or '.join(candidates)}): pip install "
        f"{'taichi==1.7.4 (Python <= 3.13)' if 'taichi' in candidates else ''}"
        f"{' or ' if len(candidates) == 2 else ''}"
        f"{'taichi-forge' if 'taichi_forge' in candidates else ''}")


def _ensure_home() -> None:
    """Taichi's import aborts the process (a C++ assertion, SIGABRT) when HOME is unset, as in some
    service and container environments: the user's home from the password database, else the
    temporary folder (where Taichi then keeps its cache)."""
    if os.environ.get("HOME"):
        return
    home = ""
    try:
        import pwd

        home = pwd.getpwuid(os.getuid()).pw_dir
    except (ImportError, KeyError, OSError):
        pass
    if not home or not os.path.isdir(home):
        import tempfile

        home = tempfile.gettempdir()
    os.environ["HOME"] = home


_ensure_home()
ti = _import_taichi()
DISTRIBUTION: str = ti.__name__
VERSION: tuple = tuple(ti.__version__)
CPU_ARCHS = (ti.x64, ti.arm64)
NDARRAY_TYPE = ti.lang._ndarray.Ndarray


def is_initialized() -> bool:
    """True when a Taichi runtime exists (started by roadx_ti or by the host program)."""
    return ti.lang.impl.get_runtime().prog is not None


def runtime_program():
    """An object that identifies the current runtime (one ti.init): Taichi's Python runtime object,
    which ti.init / ti.reset replace. Not the C++ program's pybind wrapper: a new program allocated
    at a freed one's address comes back as the old wrapper while a reference to it is held, so the
    scratch cache of kernels/grid.py took a dead runtime's buffers for live ones (intermittent
    'RuntimeError: argument not found' after a backend switch in the tests)."""
    return ti.lang.impl.get_runtime()


_fast_math_said = False     # the fast_math warning is said once per process


class RuntimeSettingsError(RuntimeError):
    """No Taichi runtime, or one whose settings the kernels cannot run under."""


def current_arch():
    """The arch of the running runtime (a ``ti`` arch object). RuntimeSettingsError when there is
    none, or when its default types are not the f32 / i32 the kernels are written for: a host's
    ``ti.init(default_fp=ti.f64)`` aborted the process in LLVM (an invalid cast), default_ip i64
    failed Taichi's type check inside the first kernel."""
    if not is_initialized():
        raise RuntimeSettingsError("Taichi is not initialised: call roadx_ti.backend.init() (or ti.init) before "
                                   "the kernels")
    cfg = ti.lang.impl.current_cfg()
    if cfg.default_fp != ti.f32 or cfg.default_ip != ti.i32:
        raise RuntimeSettingsError(f"the Taichi runtime was started with default_fp={cfg.default_fp} and "
                                   f"default_ip={cfg.default_ip}; roadx_ti's kernels need ti.f32 and ti.i32 "
                                   "(the defaults of ti.init)")
    global _fast_math_said
    if cfg.fast_math and not _fast_math_said:
        # ti.init's default: LLVM may contract and reorder float expressions, so features and
        # labels differ in the last bits from roadx_ti's own runs (which start Taichi without it)
        _fast_math_said = True
        import logging
        logging.getLogger("roadx_ti").warning(
            "the Taichi runtime runs with fast_math on (ti.init's default); roadx_ti's own runs use "
            "ti.init(..., fast_math=False), and results differ in the last bits from theirs (about 0.1 % of "
            "the labels of a road scene): start Taichi with fast_math=False for the same results")
    return cfg.arch


def cpu_threads() -> int:
    """Threads the CPU backend was started with (``cpu_max_num_threads``)."""
    return int(ti.lang.impl.current_cfg().cpu_max_num_threads)


def description() -> str:
    """e.g. 'taichi 1.7.4' or 'taichi_forge 0.7.0', for logs, reports and benchmark records."""
    return f"{DISTRIBUTION} {'.'.join(str(v) for v in VERSION)}"



def _quicker_kernel_transforms():
    """Taichi 1.7.4 redoes Python-side work in every process, offline cache or not, that gives the
    same result each time; three of its helpers are replaced here by ones that return exactly what
    Taichi's own return, faster (a road CLI run of 50 k points 8.5 -> 7.3 s, of 1 M points
    11.4 -> 10.5 s: benchmarks/RESULTS.md). tests/test_taichi_compat.py runs both versions on every call a road and
    a roof pipeline make and compares the results. taichi-forge caches these itself and is left as
    it is. Returns {name: Taichi's own function} ({} when not taichi 1.7.4).

    - ``ASTTransformerContext.get_pos_info``: a source excerpt for every AST node of every kernel
      transform (it tags the IR for error messages), each line wrapped by textwrap at 80 columns.
      For a node on one line of at most 80 printable ASCII characters textwrap gives the line back
      (Taichi's source lines carry no trailing blanks), so the excerpt is formatted directly; other
      nodes take Taichi's method once per position (a ti.func is transformed again at every call).
    - ``kernel_impl.getsourcelines``: the source of each kernel and ti.func, read again (inspect,
      tokenize) at every transform; kept per function object while its code object and its .py
      file's mtime and size stay the same (a weak key: redefined functions are read anew); any
      other source (notebook cells, wrapped functions, files gone) is read by Taichi each time.
    - ``kernel_impl._inside_class``: whether a kernel is defined in a class body, from the source
      line of the defining frame, which ``inspect.getframeinfo`` finds by searching sys.modules for
      the frame's module at every decorator; read from linecache directly where that frame's code
      is a .py file on disk, False for frozen code without source (what inspect finds there:
      nothing), Taichi's way otherwise."""
    if DISTRIBUTION != "taichi" or VERSION != (1, 7, 4):
        return {}
    try:
        import linecache
        import weakref

        from taichi.lang import kernel_impl
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
        own = {"get_pos_info": ASTTransformerContext.get_pos_info,
               "getsourcelines": kernel_impl.getsourcelines,
               "_inside_class": kernel_impl._inside_class}
        class_statements = kernel_impl._KERNEL_CLASS_STACKFRAME_STMT_RES
    except (ImportError, AttributeError):
        return {}

    excerpts = {}
    EXCERPTS_KEPT = 100_000           # distinct excerpts kept (the road and roof pipelines: ~2,000)

    def get_pos_info(self, node):
        line = node.lineno
        end_line = getattr(node, "end_lineno", None)
        head = f'File "{self.file}", line {line + self.lineno_offset}, in {self.func.func.__name__}:\n'
        start = self.indent + node.col_offset
        end = self.indent + node.end_col_offset
        if end_line == line:
            code = self.src[line - 1]
            if len(code) <= 80 and end <= 80 and code.isascii() and code.isprintable():
                if not code.strip(" "):
                    return head + "\n\n"
                if end <= start:
                    return head        # no caret: textwrap gives no hint line, so no line at all
                return head + code.rstrip(" ") + "\n" + " " * start + "^" * (end - start) + "\n"
        body = getattr(node, "body", None)
        key = (self.file, self.lineno_offset, start, end, line, end_line, type(node).__name__,
               body[0].lineno if isinstance(body, list) and body else None,
               tuple(self.src[line - 1:end_line or line]))
        excerpt = excerpts.get(key)
        if excerpt is None:
            if len(excerpts) >= EXCERPTS_KEPT:    # a long-lived host compiling ever new sources
                excerpts.clear()
            excerpt = excerpts[key] = own["get_pos_info"](self, node)[len(head):]
        return head + excerpt

    sources = weakref.WeakKeyDictionary()

    def file_state(path):
        """(mtime, size) of a Python source file on disk (what linecache.checkcache compares), or
        None: only such sources are kept or read directly, everything else goes to Taichi."""
        if not isinstance(path, str) or not path.endswith(".py"):
            return None
        try:
            state = os.stat(path)
        except (OSError, ValueError):
            return None
        return state.st_mtime_ns, state.st_size

    def getsourcelines(obj):
        code = getattr(obj, "__code__", None)
        # inspect follows __wrapped__; a file that is gone, edited or not a file is read by Taichi
        state = None if code is None or hasattr(obj, "__wrapped__") else file_state(code.co_filename)
        if state is None:
            return own["getsourcelines"](obj)
        try:
            found = sources.get(obj)
        except TypeError:                 # not weak-referenceable: not kept
            return own["getsourcelines"](obj)
        if found is None or found[0] is not code or found[1] != state:
            # new, or its code replaced in place (IPython's autoreload), or its file changed on disk
            lines, start = own["getsourcelines"](obj)
            found = sources[obj] = (code, state, tuple(lines), start)
        return list(found[2]), found[3]

    def _inside_class(level_of_class_stackframe):
        try:
            frame = sys._getframe(level_of_class_stackframe)
        except ValueError:                # as Taichi's: no frame there means not in a class
            return False
        filename = frame.f_code.co_filename
        if filename.startswith("<frozen ") and filename not in linecache.cache:
            # the importer running a module's body: frozen code has no source, so inspect finds no
            # line and Taichi's answer is False (every module-level kernel of an imported module)
            return False
        text = ""
        if file_state(filename) is not None and isinstance(frame.f_lineno, int):
            linecache.checkcache(filename)    # as inspect does: a file changed on disk is read anew
            text = linecache.getline(filename, frame.f_lineno)
        if not text:                      # not a source file on disk, or no such line: Taichi's way
            return own["_inside_class"](level_of_class_stackframe + 1)
        statement = text.strip()
        return any(pattern.match(statement) for pattern in class_statements)

    ASTTransformerContext.get_pos_info = get_pos_info
    kernel_impl.getsourcelines = getsourcelines
    kernel_impl._inside_class = _inside_class
    return own


TAICHIS_OWN = _quicker_kernel_transforms()


def _release_compile_arguments() -> bool:
    """Compiling a kernel (``Kernel.materialize``) builds an AST context that keeps the first call's
    argument tuple (``argument_data``) and ends in a reference cycle, so every array handed to a
    kernel's first call stayed alive until Python's next full garbage collection, which in a
    pipeline run seldom comes (a 4 M-point road run held 520 MB of the region merge's buffers
    that way, a 16 M-point run 1.3 GB). The context is not used once the kernel exists, so its
    arguments are let go when ``materialize`` returns. Same in taichi 1.7.4 and taichi-forge;
    returns whether the hook was installed (False where either name is missing)."""
    try:
        kernel_impl = importlib.import_module(f"{DISTRIBUTION}.lang.kernel_impl")
        own_tree_and_ctx = kernel_impl._get_tree_and_ctx
        own_materialize = kernel_impl.Kernel.materialize
    except (ImportError, AttributeError):
        return False
    made = []                         # contexts made by the materialize calls in progress

    def _get_tree_and_ctx(*args, **kwargs):
        tree, ctx = own_tree_and_ctx(*args, **kwargs)
        made.append(ctx)
        return tree, ctx

    def materialize(self, *args, **kwargs):
        depth = len(made)
        try:
            return own_materialize(self, *args, **kwargs)
        finally:
            for ctx in made[depth:]:
                ctx.argument_data = None
            del made[depth:]

    kernel_impl._get_tree_and_ctx = _get_tree_and_ctx
    kernel_impl.Kernel.materialize = materialize
    return True


RELEASES_COMPILE_ARGUMENTS = _release_compile_arguments()
