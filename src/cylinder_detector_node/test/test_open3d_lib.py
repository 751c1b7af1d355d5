"""core.open3d_lib: the detector loads Open3D's compiled module alone, not the package's
visualization start-up (Plotly, Dash, IPython: issue 27), with the same objects and results."""

import subprocess
import sys

from vizzy_runtime.testing import scaled


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=scaled(120.0), check=True)
    return out.stdout.strip()


# RANSAC and a voxel grid on a fixed cloud: what the segmentation asks of Open3D
GEOMETRY = '''
import numpy as np
pts = np.random.default_rng(0).random((2000, 3))
pts[:1000, 2] = 0.5
pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
o3d.utility.random.seed(0)
plane, inliers = pc.segment_plane(0.01, 3, 200, 0.999)
print(len(pc.voxel_down_sample(0.05).points), len(inliers), np.round(plane, 6).tolist())
'''


def test_the_node_imports_no_open3d_package() -> None:
    loaded = _run('import sys, cylinder_detector_node.node\n'
                  'print(sorted(m for m in ("open3d", "open3d.pybind", "open3d.visualization", '
                  '"dash", "plotly", "IPython") if m in sys.modules))')
    assert loaded == "['open3d.pybind']"


def test_the_compiled_module_is_the_packages_and_computes_the_same() -> None:
    narrow = _run('from cylinder_detector_node.core.open3d_lib import load\no3d = load()\n'
                  + GEOMETRY
                  + 'import open3d\n'      # the package later (a test, detect_file): the same
                  'print(o3d.__name__, open3d.geometry.PointCloud is o3d.geometry.PointCloud)')
    whole = _run('import open3d as o3d\n' + GEOMETRY)
    lines = narrow.splitlines()
    assert lines[-1] == 'open3d.pybind True'
    assert lines[0] == whole and int(whole.split()[1]) > 900


def test_without_the_compiled_module_it_is_the_package() -> None:
    name = _run('import cylinder_detector_node.core.open3d_lib as lib\n'
                'lib._pybind_file = lambda: None\nprint(lib.load().__name__)')
    assert name == 'open3d'
