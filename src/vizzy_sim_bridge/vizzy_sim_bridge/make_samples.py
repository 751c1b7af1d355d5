"""Render the small sample data under samples/ that the docs' tool examples run on.

    .venv/bin/python -m vizzy_sim_bridge.make_samples [--out samples]
        [--only mot stereo cloud objects]

Everything is rendered by this project's simulator (MuJoCo offscreen, no ROS), so a fresh clone
has a sequence, a stereo pair, a cloud and labelled object views to try the tools on, and
nothing third-party is shipped:

- ``sim-pedestrians-s0/``: the pedestrians scene (seed 0, 4 walkers, head at rest) seen by the
  left eye, MOTChallenge layout (``img1/*.jpg``, ``gt/gt.txt``, ``seqinfo.ini``) for
  ``evaluate``. The ground-truth boxes are each walker's geoms projected into the image (what the
  sim publishes on /sim/ground_truth/left/pedestrians), clipped to the image, with the fraction
  inside it as visibility: the same recipe as ``experiments/mot_budget.py --sim``.
- ``stereo/left.jpg``, ``stereo/right.jpg``: the visual_search scene (seed 0) seen by both eyes
  with the head at rest; the eyes are parallel (vergence 0), so the pair is rectified.
  ``stereo/disparity.png``: the left view's true disparity (f b / depth, KITTI's 16-bit PNG:
  value / 256, 0 unknown); ``stereo/pair.json`` the focal length and baseline for ``stereo_file``.
- ``tabletop_s30000.pcd``: the tabletop scene (seed 30000) seen by the RGB-D camera with the head
  of the bags' tabletop recording, at 320x240 (half the sensor's resolution, to keep the file
  near 1 MB), Xtion-like depth noise, as an organized binary PCD (x y z rgb, NaN where nothing
  was measured) for ``detect_file``.
- ``objects/``: 160x160 px windows of the left eye's view of that tabletop, centred on each
  visible object, with ``labels.csv`` (label = the scene's kind, box = the object's projected
  box), for ``recognize_folder`` with the foveation node's window model.

``manifest.json`` records every file's size and SHA-256 and the parameters; README.md is written
from the same numbers. Rendered images may differ in their last bits between GL drivers; the
ground truth, geometry and counts do not (the tests check those).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[3]
PARTS = ('mot', 'stereo', 'cloud', 'objects')

# The sequence: 4 walkers (the scene's default, all in the left eye's view), 2 s at 10 fps.
MOT_SEED, MOT_PEOPLE, MOT_FRAMES, MOT_FPS, MOT_JPEG_QUALITY = 0, 4, 20, 10.0, 90
MOT_NAME = f'sim-pedestrians-s{MOT_SEED}'
# The stereo pair and the cloud: tabletop(0) with the head of the bags' tabletop recording.
TABLE_SEED = 30000                            # no CNN of the project trained or validated on it
TABLE_JOINTS = (0.0, 0.2, 0.15, 0.0, 0.0)     # neck pan, neck tilt, eyes tilt, left, right eye
CLOUD_WIDTH, CLOUD_HEIGHT = 320, 240
CLOUD_NAME = f'tabletop_s{TABLE_SEED}.pcd'
# The stereo pair: the visual_search scene (rich texture, 23-67 px of disparity) with the head at
# rest (vergence 0: a rectified pair), JPEG 95 (bad-2.0 of plain SGBM as with lossless PNG, a third
# of the bytes).
STEREO_SCENE, STEREO_SEED, STEREO_JOINTS, STEREO_JPEG_QUALITY = 'visual_search', 0, (0.0,) * 5, 95
NOISE_SEED = 99                               # depth noise: SeedSequence([TABLE_SEED, 99])
OBJECT_WINDOW = 160                           # px: the foveation node's classifier window


def mot_gt_row(frame: int, track: int, uv: np.ndarray, width: int, height: int) -> str | None:
    """A MOTChallenge gt.txt row (1-based frame and id) for a walker whose corners project to uv
    (N, 2) px: their bounding box clipped to the image, the visible share as the last field;
    None when a corner is behind the camera or the clipped box is too small to see."""
    if np.isnan(uv).any():                             # partly behind the camera
        return None
    (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)
    cu0, cv0 = max(u0, 0.0), max(v0, 0.0)
    cu1, cv1 = min(u1, float(width)), min(v1, float(height))
    if cu1 - cu0 < 4 or cv1 - cv0 < 16:                # out of view
        return None
    visible = (cu1 - cu0) * (cv1 - cv0) / ((u1 - u0) * (v1 - v0))
    return (f'{frame},{track},{cu0:.2f},{cv0:.2f},{cu1 - cu0:.2f},{cv1 - cv0:.2f},1,1,'
            f'{visible:.3f}')


def pedestrian_rows(seed: int = MOT_SEED, people: int = MOT_PEOPLE, frames: int = MOT_FRAMES,
                    fps: float = MOT_FPS, image_dir: Path | None = None) -> list[str]:
    """gt.txt rows (MOT16/17 layout: frame, id, x, y, w, h, conf 1, class 1, visibility) of the
    pedestrians scene seen by the left eye with the head at rest, frame f at (f - 1) / fps s.
    With image_dir, also renders each frame there as NNNNNN.jpg; without it nothing is rendered
    (geometry only: cheap, and the same on every machine)."""
    import cv2
    import mujoco

    from vizzy_sim_bridge.core.model import EYE_CAMERA, compile_model
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.scenes import build_scene
    from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix, project
    from vizzy_vision.kinematics import CAMERA_FRAMES, JOINT_NAMES, frames_in_base

    scene = build_scene('pedestrians', seed, count=people)
    model, _ = compile_model(scene)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)                         # the head at rest (all joints 0)
    width, height = EYE_CAMERA.width, EYE_CAMERA.height
    k = camera_matrix(width, height, EYE_HFOV_DEG)
    pose = frames_in_base([0.0] * len(JOINT_NAMES))[CAMERA_FRAMES['left']]
    renderer = CameraRenderer(model, width, height) if image_dir is not None else None
    rows = []
    try:
        for f in range(frames):
            scene.update(model, data, f / fps)
            if renderer is not None and image_dir is not None:
                rgb, _ = renderer.render(data, 'left_camera')
                cv2.imwrite(str(image_dir / f'{f + 1:06d}.jpg'),
                            cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                            [cv2.IMWRITE_JPEG_QUALITY, MOT_JPEG_QUALITY])
            for box in scene.moving_ground_truth(model, data):
                row = mot_gt_row(f + 1, box['id'] + 1, project(k, pose, box['corners']),
                                 width, height)
                if row is not None:
                    rows.append(row)
    finally:
        if renderer is not None:
            renderer.close()
    return rows


def write_mot(out: Path) -> dict[str, Any]:
    """The MOTChallenge sequence under out/MOT_NAME; returns its manifest entry."""
    from vizzy_sim_bridge.core.model import EYE_CAMERA

    seq = out / MOT_NAME
    img = seq / 'img1'
    img.mkdir(parents=True, exist_ok=True)
    for old in img.glob('*.jpg'):                          # a shorter rerun leaves no extra frames
        old.unlink()
    (seq / 'gt').mkdir(exist_ok=True)
    rows = pedestrian_rows(image_dir=img)
    (seq / 'gt' / 'gt.txt').write_text('\n'.join(rows) + '\n')
    width, height = EYE_CAMERA.width, EYE_CAMERA.height
    (seq / 'seqinfo.ini').write_text(
        f'[Sequence]\nname={MOT_NAME}\nimDir=img1\nframeRate={MOT_FPS:g}\n'
        f'seqLength={MOT_FRAMES}\nimWidth={width}\nimHeight={height}\nimExt=.jpg\n')
    ids = {int(r.split(',')[1]) for r in rows}
    return {'scene': 'pedestrians', 'seed': MOT_SEED, 'people': MOT_PEOPLE, 'frames': MOT_FRAMES,
            'fps': MOT_FPS, 'width': width, 'height': height, 'camera': 'left eye, head at rest',
            'jpeg_quality': MOT_JPEG_QUALITY, 'gt_rows': len(rows), 'gt_ids': len(ids)}


def stereo_geometry() -> dict[str, Any]:
    """Focal length [px], baseline [m] and the right eye's pose in the left eye's optical frame
    (identity rotation: a rectified pair) for STEREO_JOINTS."""
    from vizzy_sim_bridge.core.model import EYE_CAMERA
    from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix
    from vizzy_vision.kinematics import CAMERA_FRAMES, frames_in_base

    frames = frames_in_base(list(STEREO_JOINTS))
    left, right = frames[CAMERA_FRAMES['left']], frames[CAMERA_FRAMES['right']]
    rotation = left[:3, :3].T @ right[:3, :3]
    offset = left[:3, :3].T @ (right[:3, 3] - left[:3, 3])
    k = camera_matrix(EYE_CAMERA.width, EYE_CAMERA.height, EYE_HFOV_DEG)
    return {'focal_px': round(float(k[0, 0]), 4), 'baseline_m': round(float(offset[0]), 6),
            'principal_point': [float(k[0, 2]), float(k[1, 2])],
            'rectified': bool(np.allclose(rotation, np.eye(3), atol=1e-9)
                              and np.allclose(offset[1:], 0.0, atol=1e-9))}


def disparity_png(disparity: np.ndarray) -> np.ndarray:
    """A disparity map [px] (NaN or inf: unknown) as KITTI's 16-bit PNG image: d * 256, 0 for
    unknown (read back: png / 256, 0 -> unknown)."""
    d = np.where(np.isfinite(disparity) & (disparity > 0), disparity, 0.0)
    return np.clip(np.round(d * 256.0), 0, 65535).astype(np.uint16)


def write_stereo(out: Path) -> dict[str, Any]:
    """stereo/left.jpg, right.jpg, disparity.png (the left view's true disparity) and
    pair.json; returns the manifest entry."""
    import cv2
    import mujoco

    from vizzy_sim_bridge.core.model import EYE_CAMERA, HeadSimulation
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.scenes import build_scene

    folder = out / 'stereo'
    folder.mkdir(parents=True, exist_ok=True)
    sim = HeadSimulation(build_scene(STEREO_SCENE, STEREO_SEED))
    data = mujoco.MjData(sim.model)
    data.qpos[:] = sim.data.qpos
    data.qpos[sim.qpos_adr] = np.asarray(STEREO_JOINTS, float)
    mujoco.mj_forward(sim.model, data)
    geometry = stereo_geometry()
    with CameraRenderer(sim.model, EYE_CAMERA.width, EYE_CAMERA.height) as renderer:
        for side in ('left', 'right'):
            rgb, depth = renderer.render(data, f'{side}_camera', depth=side == 'left')
            cv2.imwrite(str(folder / f'{side}.jpg'), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                        [cv2.IMWRITE_JPEG_QUALITY, STEREO_JPEG_QUALITY])
            if depth is not None:
                left_depth = depth.copy()
    # depth along the optical axis -> disparity d = f b / z (rectified pair)
    with np.errstate(divide='ignore'):
        disparity = geometry['focal_px'] * geometry['baseline_m'] / left_depth
    cv2.imwrite(str(folder / 'disparity.png'), disparity_png(disparity),
                [cv2.IMWRITE_PNG_COMPRESSION, 9])
    known = disparity[np.isfinite(disparity)]
    cy, cx = (int(round(c)) for c in geometry['principal_point'][::-1])
    entry = {'scene': STEREO_SCENE, 'seed': STEREO_SEED, 'joints': list(STEREO_JOINTS),
             'width': EYE_CAMERA.width, 'height': EYE_CAMERA.height, **geometry,
             'jpeg_quality': STEREO_JPEG_QUALITY,
             'true_disparity_px': [round(float(known.min()), 1), round(float(known.max()), 1)],
             'true_disparity_centre_px': round(float(disparity[cy, cx]), 2),
             'known_fraction': round(float(known.size / disparity.size), 4)}
    (folder / 'pair.json').write_text(json.dumps(entry, indent=1) + '\n')
    return entry


def write_objects(out: Path) -> dict[str, Any]:
    """objects/<name>.png: a WINDOW x WINDOW crop of the left eye's tabletop view centred on each
    object whose centre is in view and unoccluded (what the foveation node classifies around a
    fixation), and objects/labels.csv (file,label,x0,y0,x1,y1: the scene's kind and the object's
    projected box in the crop); returns the manifest entry."""
    import cv2
    import mujoco

    from vizzy_sim_bridge.core.model import EYE_CAMERA, HeadSimulation
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.scenes import BASE_IN_WORLD, geom_box_corners, tabletop
    from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix, project
    from vizzy_vision.kinematics import CAMERA_FRAMES, frames_in_base

    scene = tabletop(TABLE_SEED)
    sim = HeadSimulation(scene)
    model = sim.model
    data = mujoco.MjData(model)
    data.qpos[:] = sim.data.qpos
    data.qpos[sim.qpos_adr] = np.asarray(TABLE_JOINTS, float)
    mujoco.mj_forward(model, data)
    width, height = EYE_CAMERA.width, EYE_CAMERA.height
    k = camera_matrix(width, height, EYE_HFOV_DEG)
    pose = frames_in_base(list(TABLE_JOINTS))[CAMERA_FRAMES['left']]
    with CameraRenderer(model, width, height) as renderer:
        rgb, depth = renderer.render(data, 'left_camera', depth=True)
        rgb = rgb.copy()
    assert depth is not None
    folder = out / 'objects'
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob('*.png'):
        old.unlink()
    half = OBJECT_WINDOW // 2
    rows, skipped = ['file,label,x0,y0,x1,y1'], []
    for o in scene.objects:
        if o.role == 'support':
            continue
        (u, v), = project(k, pose, np.asarray(o.position, float))
        z = float((np.linalg.inv(pose) @ np.append(o.position, 1.0))[2])
        cu, cv = int(round(u)), int(round(v))
        if not (half <= cu <= width - half and half <= cv <= height - half):
            skipped.append(f'{o.name} (its window leaves the image)')
            continue
        if depth[cv, cu] < z - 0.5 * max(o.size) - 0.02:        # something nearer hides it
            skipped.append(f'{o.name} (occluded)')
            continue
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, o.name)
        corners = geom_box_corners(model, data, np.nonzero(model.geom_bodyid == body)[0])
        uv = project(k, pose, corners - BASE_IN_WORLD)
        x0, y0 = np.maximum(uv.min(axis=0) - (cu - half, cv - half), 0).astype(int)
        x1, y1 = np.minimum(np.ceil(uv.max(axis=0)) - (cu - half, cv - half),
                            OBJECT_WINDOW - 1).astype(int)
        crop = rgb[cv - half:cv + half, cu - half:cu + half]
        cv2.imwrite(str(folder / f'{o.name}.png'), cv2.cvtColor(crop, cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_PNG_COMPRESSION, 9])
        rows.append(f'{o.name}.png,{o.kind},{x0},{y0},{x1},{y1}')
    (folder / 'labels.csv').write_text('\n'.join(rows) + '\n')
    return {'scene': 'tabletop', 'seed': TABLE_SEED, 'joints': list(TABLE_JOINTS),
            'camera': 'left eye', 'window': OBJECT_WINDOW, 'images': len(rows) - 1,
            'labels': sorted({r.split(',')[1] for r in rows[1:]}), 'skipped': skipped}


def pcd_bytes(cloud: np.ndarray) -> bytes:
    """An organized structured cloud (H x W, fields x y z rgb as float32) as a binary PCD v0.7
    (rgb packed 0x00RRGGBB in a float, as PCL writes it)."""
    h, w = cloud.shape
    head = ('# .PCD v0.7 - rendered by vizzy_sim_bridge.make_samples\nVERSION 0.7\n'
            'FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n'
            f'WIDTH {w}\nHEIGHT {h}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {w * h}\nDATA binary\n')
    return head.encode() + np.ascontiguousarray(cloud).tobytes()


def write_cloud(out: Path) -> dict[str, Any]:
    """The organized tabletop cloud (CLOUD_NAME); returns the manifest entry."""
    import mujoco

    from vizzy_sim_bridge.core.model import RGBD_CAMERA, HeadSimulation
    from vizzy_sim_bridge.core.render import CameraRenderer
    from vizzy_sim_bridge.core.rgbd import XTION_SIGMA_COEFFICIENT, DepthProjector, noisy_depth
    from vizzy_sim_bridge.core.scenes import tabletop
    from vizzy_vision.camera import camera_matrix

    scene = tabletop(TABLE_SEED)
    sim = HeadSimulation(scene)
    data = mujoco.MjData(sim.model)
    data.qpos[:] = sim.data.qpos
    data.qpos[sim.qpos_adr] = np.asarray(TABLE_JOINTS, float)
    mujoco.mj_forward(sim.model, data)
    k = camera_matrix(CLOUD_WIDTH, CLOUD_HEIGHT, RGBD_CAMERA.hfov_deg)
    with CameraRenderer(sim.model, CLOUD_WIDTH, CLOUD_HEIGHT) as renderer:
        rgb, depth = renderer.render(data, 'rgbd_camera', depth=True)
        rgb = rgb.copy()
    assert depth is not None
    rng = np.random.default_rng(np.random.SeedSequence([TABLE_SEED, NOISE_SEED]))
    z = noisy_depth(depth, rng, XTION_SIGMA_COEFFICIENT)
    cloud = DepthProjector(k, CLOUD_WIDTH, CLOUD_HEIGHT).cloud(z, rgb)
    out.mkdir(parents=True, exist_ok=True)
    (out / CLOUD_NAME).write_bytes(pcd_bytes(cloud))
    cylinders = [o.name for o in scene.objects if o.is_cylinder and o.role != 'support']
    return {'scene': 'tabletop', 'seed': TABLE_SEED, 'joints': list(TABLE_JOINTS),
            'camera': 'rgbd', 'width': CLOUD_WIDTH, 'height': CLOUD_HEIGHT,
            'depth_noise': f'Xtion-like, sigma = {XTION_SIGMA_COEFFICIENT} z^2, '
                           f'SeedSequence([{TABLE_SEED}, {NOISE_SEED}])',
            'valid_points': int(np.isfinite(cloud['z']).sum()), 'cylinders_in_scene': cylinders}


def file_table(out: Path) -> dict[str, dict[str, Any]]:
    """{relative path: {bytes, sha256}} of every file under out but the manifest and README."""
    table = {}
    for path in sorted(p for p in out.rglob('*') if p.is_file()):
        rel = path.relative_to(out).as_posix()
        if rel in ('manifest.json', 'README.md'):
            continue
        raw = path.read_bytes()
        table[rel] = {'bytes': len(raw), 'sha256': hashlib.sha256(raw).hexdigest()}
    return table


def readme(manifest: dict[str, Any]) -> str:
    """samples/README.md from the manifest (so the two cannot disagree)."""
    mot, st, cl, ob = manifest['mot'], manifest['stereo'], manifest['cloud'], manifest['objects']
    files = manifest['files']
    total = sum(f['bytes'] for f in files.values())
    seq_bytes = sum(f['bytes'] for name, f in files.items() if name.startswith(MOT_NAME + '/'))
    table = [
        (f'`{MOT_NAME}/`',
         f"scene `pedestrians`, seed {mot['seed']}, {mot['people']} walkers, left eye with the "
         f"head at rest, {mot['frames']} frames at {mot['fps']:g} fps, "
         f"{mot['width']}x{mot['height']} JPEG (quality {mot['jpeg_quality']}); MOTChallenge "
         f"layout: `img1/`, `gt/gt.txt` ({mot['gt_rows']} boxes of {mot['gt_ids']} people; "
         'MOT16/17 rows, class 1, visibility = the share of the box inside the image), '
         f'`seqinfo.ini`; {seq_bytes / 1e6:.2f} MB',
         f'`evaluate samples/{MOT_NAME}`'),
        ('`stereo/left.jpg`, `stereo/right.jpg`',
         f"scene `{st['scene']}`, seed {st['seed']}, both eyes with the head at rest (vergence 0, "
         f"so the pair is rectified), {st['width']}x{st['height']} JPEG (quality "
         f"{st['jpeg_quality']}); true disparity {st['true_disparity_px'][0]}-"
         f"{st['true_disparity_px'][1]} px, {st['true_disparity_centre_px']} px at the centre",
         '`stereo_file samples/stereo/left.jpg samples/stereo/right.jpg '
         f"--focal {st['focal_px']} --baseline {st['baseline_m']}`"),
        ('`stereo/disparity.png`',
         "the left view's true disparity (f b / depth of the render), KITTI's 16-bit PNG: value / "
         f"256 px, 0 where unknown ({st['known_fraction']:.0%} known)",
         'compare with `stereo_file ... --out d.npy`'),
        ('`stereo/pair.json`',
         'focal length [px], baseline [m], principal point and those disparities', ''),
        (f'`{CLOUD_NAME}`',
         f"scene `tabletop`, seed {cl['seed']}, the RGB-D camera with the head at {cl['joints']} "
         '(neck pan, neck tilt, eyes tilt, left, right eye: the bags\' tabletop recording), '
         f"{cl['width']}x{cl['height']} (half the sensor's resolution, to keep the file small), "
         'organized binary PCD (x y z rgb, NaN where nothing was measured; '
         f"{cl['valid_points']} valid points), depth noise {cl['depth_noise']}; cylinders in "
         f"the scene: {', '.join(cl['cylinders_in_scene'])}",
         f'`detect_file samples/{CLOUD_NAME}`'),
        ('`objects/*.png`, `objects/labels.csv`',
         f"the left eye's view of the same scene: a {ob['window']}x{ob['window']} px window "
         f"centred on each of {ob['images']} objects whose centre is in view and unoccluded "
         f"({', '.join(ob['labels'])}; left out: {'; '.join(ob['skipped']) or 'none'}); "
         '`labels.csv`: `file,label,x0,y0,x1,y1` with the object\'s projected box in the window',
         '`recognize_folder samples/objects --model '
         'src/foveation_node/foveation_node/models/fovea_cnn.pt --size 0`'),
    ]
    rows = '\n'.join(f'| {a} | {b} | {c} |' for a, b, c in table)
    return f"""# Sample data

Small inputs for the file tools, so that the docs' examples run on a fresh clone. Everything here
was rendered by this project's own simulator (`vizzy_sim_bridge`, MuJoCo offscreen, no ROS) and is
under the project's licence (Apache-2.0, as every package.xml says); nothing third-party is
included. Regenerate with

    .venv/bin/python -m vizzy_sim_bridge.make_samples --out samples \\
        [--only mot stereo cloud objects]

`manifest.json` lists each file's size and SHA-256 and the parameters. Rendered pixels may differ
in their last bits with another GL driver; the ground truth, geometry and counts do not
(`src/vizzy_sim_bridge/test/test_samples.py` checks them against the generator).
{len(files)} files, {total / 1e6:.2f} MB in all.

The tabletop seed, {TABLE_SEED}, is outside every seed range the packaged classifiers were
trained or validated on (cylinder patches: trained on 0-149, held out from 10000; foveation
window model: trained on 10000-10479, validated on 20000-20039), so the tools' results on it are
not recall of training data. The pedestrians are tracked with OpenCV's HOG detector (not
trained here).

| path | what | try |
|---|---|---|
{rows}
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--out', type=Path, default=REPO / 'samples', help='output folder (samples/)')
    ap.add_argument('--only', nargs='+', choices=PARTS, default=list(PARTS),
                    help='render only these parts (the manifest keeps the others\' entries)')
    args = ap.parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = out / 'manifest.json'
    manifest: dict[str, Any] = {}
    if manifest_path.is_file():
        try:
            manifest = json.loads(manifest_path.read_text())
        except ValueError:
            print(f'{manifest_path}: not JSON; writing a new one', file=sys.stderr)
    writers = {'mot': write_mot, 'stereo': write_stereo, 'cloud': write_cloud,
               'objects': write_objects}
    for part in args.only:
        print(f'rendering {part} ...', file=sys.stderr)
        manifest[part] = writers[part](out)
    missing = [p for p in PARTS if p not in manifest]
    if missing:
        print(f'no manifest entry for {", ".join(missing)}: render them too (--only)',
              file=sys.stderr)
        return 2
    manifest['generator'] = 'python -m vizzy_sim_bridge.make_samples'
    manifest['files'] = file_table(out)
    manifest_path.write_text(json.dumps(manifest, indent=1, sort_keys=True) + '\n')
    (out / 'README.md').write_text(readme(manifest))
    total = sum(f['bytes'] for f in manifest['files'].values())
    print(f'{len(manifest["files"])} files, {total / 1e6:.2f} MB under {out}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
