"""Pickles that hold data only: a checkpoint's state, written and read back without running code.

A plain :func:`pickle.loads` calls whatever functions its bytes name, so a forged checkpoint runs the forger's
code. A run's state holds pyribs archives, emitters and schedulers with their ``numpy.random.Generator`` states,
which nothing but pickle stores exactly, so this keeps pickle and restricts it, as ``torch.load(weights_only=True)``
does: the reader resolves only the globals of :func:`allowed_globals`, the classes and pickling helpers of the
libraries whose objects a run's state holds (builtins' containers, numpy arrays, scalars and generators, the pyribs
archives, emitters, rankers and schedulers, scipy's Halton sequence, and the dsage_ray classes a state holds). A
pickle naming anything else (``os.system``, ``builtins.eval``, ``getattr``, a class outside the list) is refused
before it is called.

Torch tensors are not pickled at all: torch's own pickle of a tensor stores its storage as a nested
``torch.load(weights_only=False)``. :func:`dumps` takes each tensor out as a persistent id (dtype name, shape and raw
bytes) and :func:`loads` rebuilds it from those, with the dtype looked up in a fixed table.

What is left to a forger is what any data file allows: wrong values, and objects of the allowed classes built with
wrong arguments (a huge archive, say). Those fail or mislead; they run no code of the forger's.
"""

from __future__ import annotations

import collections
import functools
import io
import pickle
import sys
from typing import Any, Callable

#: The persistent-id tag of a tensor: ``("torch.tensor", dtype name, shape, bytes)``.
_TENSOR = "torch.tensor"
#: The torch dtypes a tensor may have in a state (names as ``str(dtype)`` gives them, without ``torch.``).
_TENSOR_DTYPES = ("float64", "float32", "float16", "bfloat16", "int64", "int32", "int16", "int8", "uint8", "bool")

#: The dsage_ray classes a run's state holds (module, qualified name); only plain data and emitters.
_OWN_CLASSES = (
    ("dsage_ray.types", "EvaluationResult"),
    ("dsage_ray.qd.emitters", "MapElitesBitmapEmitter"),
    ("dsage_ray.qd.emitters", "RandomEmitter"),
    ("dsage_ray.qd.emitters", "HaltonEmitter"),
    ("dsage_ray.qd.emitters", "CrossEntropyEmitter"),
)
#: pyribs classes by their public names (their private modules move between releases; the allowlist is built from
#: where each one lives in the installed pyribs).
_RIBS_CLASSES = {
    "ribs.archives": ("GridArchive", "CVTArchive", "SlidingBoundariesArchive", "ArrayStore", "ArchiveStats"),
    "ribs.emitters": ("EvolutionStrategyEmitter", "GaussianEmitter", "IsoLineEmitter"),
    "ribs.emitters.opt": ("CMAEvolutionStrategy", "SeparableCMAEvolutionStrategy", "LMMAEvolutionStrategy",
                          "OpenAIEvolutionStrategy"),
    "ribs.emitters.rankers": ("ImprovementRanker", "TwoStageImprovementRanker", "ObjectiveRanker",
                              "TwoStageObjectiveRanker", "RandomDirectionRanker", "TwoStageRandomDirectionRanker"),
    "ribs.schedulers": ("Scheduler", "BanditScheduler"),
}
#: Functions numpy's pickles call to rebuild arrays, scalars and random generators (old and new module names).
_NUMPY_FUNCTIONS = (
    ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"), ("numpy.core.multiarray", "scalar"),
    ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
    ("numpy.random._pickle", "__generator_ctor"), ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
)
_BUILTIN_CLASSES = (set, frozenset, complex, slice, range, bytearray, collections.OrderedDict, collections.deque,
                    collections.Counter, collections.defaultdict)


class UnsafePickleError(pickle.UnpicklingError):
    """A pickle that names a global outside :func:`allowed_globals` (it was not called), or a malformed tensor."""


def dumps(obj: Any) -> bytes:
    """``obj`` pickled (protocol 5) with every torch tensor stored as data (module docstring)."""
    buffer = io.BytesIO()
    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buffer.getvalue()


#: ``resolve(module, name)``: the object a pickle may name beyond :func:`allowed_globals`, or None to refuse it.
Resolver = Callable[[str, str], Any]


def loads(data: bytes, *, also: Resolver | None = None, what: str = "a checkpoint") -> Any:
    """Restores what :func:`dumps` wrote, calling only :func:`allowed_globals`.

    Args:
        data: The pickle.
        also: Resolves what a third-party file's pickle names beyond the allowlist (another library's data classes,
            or stand-ins that record an object's state without calling its code); None: nothing more.

    Raises:
        UnsafePickleError: The bytes name a global outside the allowlist (it names the global), or hold a malformed
            tensor.
        pickle.UnpicklingError, EOFError, ValueError, TypeError: Bytes that are no pickle, or a truncated one.
    """
    return _Unpickler(io.BytesIO(data), also=also, what=what).load()


@functools.cache
def allowed_globals() -> dict[tuple[str, str], Any]:
    """``{(module, name): object}`` of everything a pickle read by :func:`loads` may name."""
    import importlib

    import numpy as np
    import numpy.random

    allowed: dict[tuple[str, str], Any] = {("builtins", cls.__name__) if cls.__module__ == "builtins"
                                           else (cls.__module__, cls.__qualname__): cls for cls in _BUILTIN_CLASSES}
    for module, name in _NUMPY_FUNCTIONS + _OWN_CLASSES:
        # numpy 1 pickles name numpy.core, numpy 2 numpy._core: both map to the installed function (importing the
        # other name only warns or fails).
        for where in dict.fromkeys((module.replace("numpy.core.", "numpy._core."), module)):
            try:
                allowed[(module, name)] = getattr(importlib.import_module(where), name)
                break
            except (ImportError, AttributeError):
                continue
    numpy_classes = [np.dtype, np.ndarray, numpy.random.Generator, numpy.random.RandomState,
                     numpy.random.SeedSequence, numpy.random.PCG64, numpy.random.PCG64DXSM, numpy.random.MT19937,
                     numpy.random.Philox, numpy.random.SFC64]
    numpy_classes += [cls for cls in vars(np).values() if isinstance(cls, type) and issubclass(cls, np.generic)]
    numpy_classes += [cls for cls in vars(np.dtypes).values() if isinstance(cls, type) and issubclass(cls, np.dtype)]
    for cls in numpy_classes:
        allowed[("numpy", cls.__name__)] = cls  # numpy pickles name some classes by the top-level module
        allowed[(cls.__module__, cls.__qualname__)] = cls
    for module, names in _RIBS_CLASSES.items():
        for name in names:
            cls = getattr(importlib.import_module(module), name)
            allowed[(cls.__module__, cls.__qualname__)] = cls
    from ribs.emitters.opt import CMAEvolutionStrategy

    cma_module = sys.modules[CMAEvolutionStrategy.__module__]
    if hasattr(cma_module, "DecompMatrix"):  # CMA-ES's covariance, a private class of pyribs' CMA-ES module
        allowed[(cma_module.__name__, "DecompMatrix")] = cma_module.DecompMatrix
    from scipy.stats import qmc

    allowed[(qmc.Halton.__module__, qmc.Halton.__qualname__)] = qmc.Halton
    return allowed


class _Pickler(pickle.Pickler):
    def persistent_id(self, obj: Any) -> Any:
        torch = sys.modules.get("torch")  # a state without torch imported holds no tensor
        if torch is None or not isinstance(obj, torch.Tensor):
            return None
        dtype = str(obj.dtype).removeprefix("torch.")
        if dtype not in _TENSOR_DTYPES:
            raise pickle.PicklingError(f"a checkpoint cannot hold a tensor of dtype {obj.dtype}")
        flat = obj.detach().cpu().contiguous().reshape(-1)
        return (_TENSOR, dtype, tuple(obj.shape), flat.view(torch.uint8).numpy().tobytes())


class _Unpickler(pickle.Unpickler):
    def __init__(self, file: io.BytesIO, *, also: Resolver | None, what: str) -> None:
        super().__init__(file)
        self._also, self._what = also, what

    def find_class(self, module: str, name: str) -> Any:
        found = allowed_globals().get((module, name))
        if found is None and self._also is not None:
            found = self._also(module, name)
        if found is None:
            raise UnsafePickleError(f"it names {module}.{name}, which {self._what} may not hold (only data "
                                    f"classes are read; nothing it names was called)")
        return found

    def persistent_load(self, pid: Any) -> Any:
        if not (isinstance(pid, tuple) and len(pid) == 4 and pid[0] == _TENSOR and pid[1] in _TENSOR_DTYPES
                and isinstance(pid[2], tuple) and all(isinstance(n, int) and n >= 0 for n in pid[2])
                and isinstance(pid[3], bytes)):
            raise UnsafePickleError(f"a malformed tensor record ({str(pid)[:80]})")
        import numpy as np
        import torch

        _, name, shape, data = pid
        dtype = getattr(torch, name)
        if len(data) != int(np.prod(shape, dtype=np.int64)) * dtype.itemsize:
            raise UnsafePickleError(f"a tensor record of shape {shape} and dtype {name} holds {len(data)} bytes")
        if not data:  # an empty uint8 tensor has no stride to view as another dtype
            return torch.empty(shape, dtype=dtype)
        return torch.from_numpy(np.frombuffer(data, dtype=np.uint8).copy()).view(dtype).reshape(shape)

