"""brush_env.engine: the discrete flexible multibody (DFM) toothbrush engine (numpy + numba only).

Nothing here imports gymnasium, torch or matplotlib.  Entry points: ``Simulator``, ``SimSettings``,
``load_brush``/``load_scene``.  Robot motions (trajectories) live in ``brush_env.motion``.
"""

from ..kernel_cache import purge_stale_kernels

# the bristle models register themselves by name (bristles.register_bristle_model): the full
# chain "dfm" through simulator -> chain, the reduced model "prb" here
from . import prb as _prb  # noqa: E402,F401
from .config import (
    BristleConfig,
    BrushConfig,
    ConfigError,
    Material,
    Section,
    configs_dir,
    load_brush,
    load_materials,
)
from .fidelity import Fidelity, load_fidelity
from .numba_inline import install as install_numba_inline
from .numba_linking import install as install_numba_linking
from .numba_loading import install as install_numba_loading
from .numba_lowering import install as install_numba_lowering
from .scene import Cylinder, MeshPlate, Plane, Scene, load_scene
from .simulator import (
    PenetrationWarning,
    SimSettings,
    SimulationDivergence,
    Simulator,
    State,
    StepResult,
)

__all__ = [
    "BristleConfig",
    "BrushConfig",
    "ConfigError",
    "Material",
    "Section",
    "configs_dir",
    "load_brush",
    "load_materials",
    "Fidelity",
    "load_fidelity",
    "SimSettings",
    "PenetrationWarning",
    "SimulationDivergence",
    "Simulator",
    "State",
    "StepResult",
    "Plane",
    "Cylinder",
    "MeshPlate",
    "Scene",
    "load_scene",
]

# before any kernel loads from numba's cache (none runs at import; numba loads a kernel's cache
# at its first call): a cached kernel may carry the old code of a callee in another module that
# changed since (kernel_cache.purge_stale_kernels)
purge_stale_kernels()
# before any kernel compiles: numba's inlining without its two defensive copies of each callee's
# IR (a quarter of the first start's compile; the machine code the same, numba_inline.py)
install_numba_inline()
# ... and its lowering without the loads and zero-fills NRT would need (the kernels run without
# NRT): most of LLVM's SROA time in the first start's compile (numba_lowering.py)
install_numba_lowering()
# ... and its linking of a kernel's callees as internal copies, so LLVM can drop the record fields a
# call passes and the callee never reads: -14 % of the step's instructions (numba_linking.py)
install_numba_linking()
# ... and its loading of a cached kernel without installing the compiler's lowering registries
# (a compile installs them itself): 0.37 s of every warm start (numba_loading.py)
install_numba_loading()
