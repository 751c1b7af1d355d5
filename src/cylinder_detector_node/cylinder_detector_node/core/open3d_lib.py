"""Open3D's geometry without the rest of its Python package's start-up (issue 27).

`import open3d` runs open3d/__init__.py, which also imports open3d.visualization (Plotly, Dash,
IPython, Werkzeug, Pydantic: about 32 MB of RSS and 3 s of CPU in every detector process and its
standby) and open3d.ml, none of which the detector uses. Open3D's algorithms live in one compiled
module, open3d.pybind (geometry, utility, core, ...), which the package re-exports as
open3d.geometry, open3d.utility, ...: load() loads that module alone, so `o3d.geometry.PointCloud`,
`o3d.utility.Vector3dVector`, `o3d.utility.random.seed` are the same objects as through the
package. When the package is already imported (a test, detect_file's PCD reader, core.scene's ray
casting), or its layout is not the expected one (another Open3D release), it is `import open3d`,
so nothing breaks: the package imported later reuses the loaded module (sys.modules).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

PACKAGE = 'open3d'
PYBIND = 'open3d.pybind'


def _pybind_file() -> Path | None:
    """The compiled open3d.pybind module next to the package's __init__.py, without running it."""
    spec = importlib.util.find_spec(PACKAGE)     # a top-level package: found, not executed
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = Path(folder) / f'pybind{suffix}'
            if path.is_file():
                return path
    return None


def load() -> ModuleType:
    """Open3D's compiled module (geometry, utility, ...), or the whole package (module
    docstring)."""
    package = sys.modules.get(PACKAGE)
    if package is not None and hasattr(package, 'geometry'):
        return package
    loaded = sys.modules.get(PYBIND)
    if loaded is not None:
        return loaded
    try:
        path = _pybind_file()
        spec = (importlib.util.spec_from_file_location(PYBIND, path)
                if path is not None else None)
        if spec is None or spec.loader is None:
            raise ImportError(f'no compiled {PYBIND} module in the {PACKAGE} package')
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        if not (hasattr(module, 'geometry') and hasattr(module, 'utility')):
            raise ImportError(f'{path} has no geometry and utility')
    except ImportError:
        import open3d  # the whole package: its own start-up, its own errors
        return open3d
    sys.modules[PYBIND] = module
    return module
