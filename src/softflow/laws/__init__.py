"""The library's physical laws as compiled scalar functions (numba).

Each law is a plain function of floats that returns its value and its partial
derivatives, compiled once per install (``cache=True``) and callable from
other compiled code as it is; the array functions of
:mod:`softflow.correlations` are thin loops over them, so that a law is
written once. Settings reach the laws as arguments, never as module globals
(numba freezes globals into its cache).

``NUMBA_DISABLE_JIT=1`` runs the same functions as plain Python: for
debugging and coverage, not a second implementation.

The cache: numba keys a cached function on its own source file only, so an
edit of a law in another file that it calls would leave a stale cache. The
locators below (tried before numba's own, for the functions of this package
only) key every function here on the text of all of this package's modules
and softflow's version instead, as they were when the function's module was
imported (a process that compiles a law later saves it under the text it was
built from). Writes are numba's own (a temporary file
renamed into place), so concurrent first compiles (pytest-xdist or Dask
workers) are safe: the last one wins with identical contents.
"""
from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import numba
from numba.core import caching, cgutils, types
from numba.extending import intrinsic

from .. import __version__

_PACKAGE = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=8)
def _stamp_of(files: tuple) -> bytes:
    h = hashlib.sha256(__version__.encode())
    for name, _, _ in files:
        h.update(name.encode())
        h.update((_PACKAGE / name).read_bytes())
    return h.digest()


def source_stamp() -> bytes:
    """SHA-256 of softflow's version and of every module of this package (name
    and text, as they are now: files are hashed again when their modification
    time or size changes): the key of every cached compiled law."""
    files = tuple(sorted((path.name, st.st_mtime_ns, st.st_size)
                         for path in _PACKAGE.glob("*.py") for st in [path.stat()]))
    return _stamp_of(files)


#: each compiled law's stamp, taken when its module was imported (the text the
#: process compiles is the text it imported, whatever the files say later)
_STAMPS: dict = {}


def _ours(py_file) -> bool:
    try:
        return Path(py_file).resolve().parent == _PACKAGE
    except (OSError, TypeError):
        return False


def _keyed_on_package(base):
    """A subclass of numba's cache locator ``base`` that takes only this
    package's functions and stamps them with :func:`source_stamp`."""

    class Locator(base):
        def get_source_stamp(self):
            return self.stamp

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _ours(py_file):
                return None
            self = super().from_function(py_func, py_file)
            if self is not None:
                self.stamp = _STAMPS.get(py_func) or source_stamp()
            return self

    Locator.__name__ = Locator.__qualname__ = "Softflow" + base.__name__
    return Locator


def _numba_class(name):
    # numba's names (public from 0.61 on, with a leading underscore before)
    return getattr(caching, name, None) or getattr(caching, "_" + name)


def _install_locators():
    classes = _numba_class("CacheImpl")._locator_classes
    if any(getattr(c, "__name__", "").startswith("Softflow") for c in classes):
        return
    ours = [_keyed_on_package(_numba_class(name)) for name in
            ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    classes[:0] = ours


_install_locators()

_NO_CACHE_WARNED = []


def inline(function):
    """Compile ``function`` into each compiled caller at numba's IR level
    (``inline='always'``), with :func:`jit`'s semantics, not as a library
    of its own. For the step loop's stages (softflow.laws.stepper): numba
    links every callee's LLVM module into each caller's and optimizes it
    again there, so the residual, reached through five layers of callers,
    was optimized five times over (the first compile after an installation
    31 -> 110 s). The residual is now reached by its address instead
    (:func:`call_native`), and so are the banded and sparse LUs; each
    inlined copy is still typed and lowered again in its caller, so the
    loops keep their copies few (one call of the chord iterations where
    there were two: the step loop's own compile 74 -> 63 s of CPU; the
    restarts' probes call the solve compiled apart: 62 -> 51 s)."""
    return numba.njit(inline="always", nogil=True, error_model="numpy")(function)


def jit(function):
    """Compile ``function`` as every law is: cached (see the module); NumPy's
    floating-point semantics (a division by zero gives inf or nan, as the
    array code it replaced did, instead of raising); no fastmath (the laws'
    bits are IEEE). Where no cache directory can be written (a read-only
    installation and home), the law is compiled in memory for this process,
    with one warning, instead of failing."""
    options = dict(nogil=True, error_model="numpy")
    # the stamp of the package's text now, as this module is imported: a law
    # compiled later in a long process is saved under the text it was built
    # from, not under the text of files edited since (which would hand their
    # stamp a stale compilation)
    _STAMPS[function] = source_stamp()
    try:
        return numba.njit(cache=True, **options)(function)
    except RuntimeError as err:         # numba: "cannot cache function ...: no locator"
        if "cannot cache" not in str(err):
            raise
        if not _NO_CACHE_WARNED:
            import warnings
            _NO_CACHE_WARNED.append(True)
            warnings.warn("softflow's compiled laws cannot be cached (no writable cache "
                          f"directory: {err}); they are compiled in memory at each start. "
                          "Set NUMBA_CACHE_DIR to a writable directory to keep them",
                          RuntimeWarning, stacklevel=2)
        return numba.njit(cache=False, **options)(function)


def _borrow_codegen(context, builder, ty, value):
    """:func:`borrowed`'s LLVM value for ``value`` of numba type ``ty``: an
    array's struct with its meminfo and parent NULL, a tuple's items each
    so, anything else as it is."""
    if isinstance(ty, types.Array):
        src = context.make_array(ty)(context, builder, value)
        out = context.make_array(ty)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, field, getattr(src, field))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()
    if isinstance(ty, types.BaseTuple):
        items = [_borrow_codegen(context, builder, t, builder.extract_value(value, i))
                 for i, t in enumerate(ty)]
        return context.make_tuple(builder, ty, items)
    return value


if numba.config.DISABLE_JIT:
    def borrowed(value):
        """``value`` itself (pure-Python mode: see the compiled version)."""
        return value
else:
    @intrinsic
    def borrowed(typingctx, value):
        """``value`` (an array, or a tuple of arrays and scalars, nested) with
        each array a view that owns no reference to its memory (numba's
        meminfo NULL). numba counts references to an array atomically at
        every call that passes it and every view taken of it (a `lock`
        instruction each, ~20 cycles); the step loop passes some twenty arrays
        through each of its calls, hundreds of times a step, and those counts
        were most of a small network's step. A borrowed view is valid while
        the array it was taken from is held: use it only on arrays that the
        caller of the compiled function holds (its arguments), and never
        return one to Python (it would come back as an array that does not
        own its data)."""
        def codegen(context, builder, sig, args):
            return _borrow_codegen(context, builder, value, args[0])
        return value(value), codegen


#: the arrays a user component's callback receives (x, S, F, raw, Sout), in order
CALLBACK_ARRAYS = 5

if numba.config.DISABLE_JIT:
    def call_user(address, key, t, dt, jac, x, S, F, raw, Sout):
        """The user component's callback ``key`` (pure-Python mode: called
        directly, see the compiled version)."""
        from ..solve.usercall import dispatch
        return dispatch(key, float(t), float(dt), bool(jac), x, S, F, raw, Sout)
else:
    @intrinsic
    def call_user(typingctx, address, key, t, dt, jac, x, S, F, raw, Sout):
        """Call the C function at ``address`` (int64) as ``int64 f(int64 key,
        double t, double dt, int64 jac, double *x, int64 n_x, double *S,
        int64 n_S, double *F, int64 n_F, double *raw, int64 n_raw, double
        *Sout, int64 n_Sout)``, which evaluates a user component's group in
        place: its kernel compiled by numba (:mod:`softflow.solve.usercompile`,
        ``key`` the address of its layout), or softflow's callback into Python
        (:mod:`softflow.solve.usercall`, a ctypes function that takes the
        interpreter's lock itself). Each array (contiguous float64, as the loop's own are) is
        passed by its data pointer and its size (Sout's 0: no states wanted).
        Returns the callback's code (0: done)."""
        arrays = (x, S, F, raw, Sout)
        for a in arrays:
            if not (isinstance(a, types.Array) and a.ndim == 1 and a.dtype == types.float64
                    and a.layout == "C"):
                return None
        sig = types.int64(address, key, t, dt, jac, *arrays)

        def codegen(context, builder, sig, args):
            from llvmlite import ir
            i64, f64 = ir.IntType(64), ir.DoubleType()
            ptr = f64.as_pointer()
            fnty = ir.FunctionType(i64, [i64, f64, f64, i64] + [ptr, i64] * CALLBACK_ARRAYS)
            at = context.cast(builder, args[0], sig.args[0], types.int64)
            fn = builder.inttoptr(at, fnty.as_pointer())
            head = [context.cast(builder, args[1], sig.args[1], types.int64),
                    context.cast(builder, args[2], sig.args[2], types.float64),
                    context.cast(builder, args[3], sig.args[3], types.float64),
                    context.cast(builder, args[4], sig.args[4], types.int64)]
            data = []
            for ty, value in zip(sig.args[5:], args[5:]):
                arr = context.make_array(ty)(context, builder, value)
                data += [arr.data, arr.nitems]
            return builder.call(fn, head + data)
        return sig, codegen


if numba.config.DISABLE_JIT:
    def call_signal(address, key, t):
        """The Python signal ``key`` at t (pure-Python mode: called directly,
        see the compiled version)."""
        from ..solve.usercall import signal_value
        return signal_value(key, float(t))
else:
    @intrinsic
    def call_signal(typingctx, address, key, t):
        """Call the C function at ``address`` as ``double f(int64 key, double
        t)``: a source's signal given as a Python function, called back
        (:mod:`softflow.solve.usercall`); its value [SI], or NaN where it
        raised."""
        sig = types.float64(address, key, t)

        def codegen(context, builder, sig, args):
            from llvmlite import ir
            i64, f64 = ir.IntType(64), ir.DoubleType()
            fnty = ir.FunctionType(f64, [i64, f64])
            at = context.cast(builder, args[0], sig.args[0], types.int64)
            fn = builder.inttoptr(at, fnty.as_pointer())
            return builder.call(fn, [context.cast(builder, args[1], sig.args[1], types.int64),
                                     context.cast(builder, args[2], sig.args[2], types.float64)])
        return sig, codegen


def _contiguous(ty) -> bool:
    """Whether every array in ``ty`` (nested in tuples) is C-contiguous: the
    layout :func:`native_address` compiles a callee for (a caller's
    array of another layout would reach code that assumes this one)."""
    if isinstance(ty, types.BaseTuple):
        return all(_contiguous(t) for t in ty)
    return not isinstance(ty, types.Array) or ty.layout == "C"


def _plain(ty):
    """``ty`` without literal values (nested in tuples): the type a callee
    compiled from Python's values takes."""
    if isinstance(ty, types.BaseTuple):
        return types.BaseTuple.from_types([_plain(t) for t in ty])
    return types.unliteral(ty)


def types_key(tys) -> int:
    """A 62-bit key of the numba types ``tys`` (literal values aside): what
    :func:`call_native` checks, before it calls, against the key of the
    types the callee was compiled for."""
    text = repr(tuple(str(_plain(t)) for t in tys))
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little") >> 2


#: pure-Python mode's stand-ins for addresses: {address: function}
_NATIVE_BY_KEY: dict = {}

if numba.config.DISABLE_JIT:
    def call_native(address, key, args):
        """``function(*args)`` for the function :func:`native_address` gave
        ``address`` (pure-Python mode: see the compiled version)."""
        return _NATIVE_BY_KEY[int(address)](*args)
else:
    @intrinsic
    def call_native(typingctx, address, key, args):
        """Call the compiled function whose native entry is at ``address``
        (int64, from :func:`native_address`) with the tuple ``args``, in
        numba's own calling convention, as numba calls one compiled function
        from another, but through the address: the callee is compiled (and
        cached) on its own, once, and not linked into the caller, so a
        caller does not compile what it reaches only this way (the step
        loop's residual, and its banded and sparse LUs, which only the runs
        that use them compile). The callee must return an int64; ``key``
        (:func:`native_address`'s) is the :func:`types_key` of the types it
        was compiled for, and a call whose arguments have other types
        raises RuntimeError instead of calling it (an address of the wrong
        callee would read its arguments wrongly). An exception the callee
        raises reaches the caller's caller as from a direct call."""
        if not isinstance(args, types.BaseTuple) or not _contiguous(args):
            return None
        expected = types_key(args.types)
        sig = types.int64(address, key, args)

        def codegen(context, builder, sig, llargs):
            from llvmlite import ir
            from numba.core.callconv import excinfo_t
            i64 = ir.IntType(64)
            given = context.cast(builder, llargs[1], sig.args[1], types.int64)
            with builder.if_then(builder.icmp_signed("!=", given, ir.Constant(i64, expected)),
                                 likely=False):
                context.call_conv.return_user_exc(
                    builder, RuntimeError,
                    ("softflow: a compiled function reached by its address with other "
                     "argument types than it was compiled for",))
            argtys = list(sig.args[2])
            values = [builder.extract_value(llargs[2], i) for i in range(len(argtys))]
            call_conv = context.call_conv
            fnty = call_conv.get_function_type(types.int64, argtys)
            at = context.cast(builder, llargs[0], sig.args[0], types.int64)
            fn = builder.inttoptr(at, fnty.as_pointer())
            retty = call_conv.get_return_type(types.int64).pointee
            ret = cgutils.alloca_once(builder, retty)
            builder.store(cgutils.get_null_value(retty), ret)
            excinfo = cgutils.alloca_once(builder, ir.PointerType(excinfo_t))
            packed = list(call_conv._get_arg_packer(argtys).as_arguments(builder, values))
            code = builder.call(fn, [ret, excinfo] + packed)
            # an exception the callee raised goes on up, as from a direct call
            status = call_conv._get_return_status(builder, code, builder.load(excinfo))
            with cgutils.if_unlikely(builder, status.is_error):
                call_conv.return_status_propagate(builder, status)
            return context.get_returned_value(builder, types.int64, builder.load(ret))
        return sig, codegen


#: compiled addresses and keys by (function, the arguments' fingerprint)
_ADDRESSES: dict = {}


def native_address(function, args) -> tuple:
    """(address, key) of ``function`` (a :func:`jit` function returning an
    int64) compiled for the types of ``args`` (loaded from numba's cache, or
    compiled and cached now), for :func:`call_native`; found once a process
    for each set of types (the arguments' fingerprint, numba's own C
    function: ~0.3 us, where their numba types cost ~100 us). Pure-Python
    mode: a stand-in address that :func:`call_native` looks up, key 0."""
    if numba.config.DISABLE_JIT:
        for k, f in _NATIVE_BY_KEY.items():
            if f is function:
                return k, 0
        at = len(_NATIVE_BY_KEY) + 1
        _NATIVE_BY_KEY[at] = function
        return at, 0
    try:
        from numba._dispatcher import compute_fingerprint
        known = (function, compute_fingerprint(tuple(args)))
    except (ImportError, ValueError, TypeError):     # numba's internals moved
        known = None
    got = _ADDRESSES.get(known) if known is not None else None
    if got is None:
        sig = tuple(numba.typeof(a) for a in args)
        cres = function.overloads.get(sig)
        if cres is None:
            function.compile(sig)
            cres = function.overloads[sig]
        at = int(cres.library.get_pointer_to_function(cres.fndesc.mangled_name))
        if not at:
            raise RuntimeError(f"numba gave no address for {function.__name__}{sig}")
        got = (at, types_key(sig))
        if known is not None:
            _ADDRESSES[known] = got
    return got
