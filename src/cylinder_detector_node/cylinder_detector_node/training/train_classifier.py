"""train_cylinder_classifier: train the pre-attention patch CNN (thesis section 4.3.2) on
simulated tabletops.

    ros2 run cylinder_detector_node train_cylinder_classifier [--scenes 150] [--poses 3]
        [--epochs 15]
    python -m cylinder_detector_node.training.train_classifier --out my_model.pt

Data, the thesis's semi-automatic way: vizzy_sim_bridge's tabletop(seed) scenes (cylinders: cans,
bottles, jars, lying cans and pipes; not: boxes, spheres, U-shaped handles) rendered by the RGB-D
camera from random head poses, segmented by our own 3D segmentation (section 4.3.1), each
cluster's image box cut out of the RGB image, labelled from the scene's ground truth
(patch_data.label_cluster), mirror augmentation. Training scenes are seeds 0..scenes-1, held-out
scenes seeds HELD_OUT_SEED.. (never trained on); the held-out accuracy is printed and stored in
the model's metadata. The rendered patches are cached (--cache) so retraining skips rendering.
Needs offscreen OpenGL (EGL or OSMesa) for the renderer.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path

# one BLAS / OpenMP thread: the fits' small matrices only contend on a shared machine
for _v in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_v, '1')

import numpy as np  # noqa: E402

from vizzy_vision.optional import main_needing_simulator  # noqa: E402

HELD_OUT_SEED = 10000
DEFAULT_CACHE = (Path(os.environ.get('XDG_CACHE_HOME', Path.home() / '.cache')) / 'vizzy'
                 / 'cylinder_patches.npz')


def render_dataset(seeds: list[int], poses: int, desc: str) -> dict[str, np.ndarray]:
    """Patches, labels, purity, Eq. 4.4 fit quality and scene seed of every cluster."""
    from tqdm import tqdm

    from .patch_data import frame_patches
    from .sim_frames import SimRenderer, random_joints
    r = SimRenderer()
    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ('patches', 'labels', 'purity', 'fit_quality', 'seed')}
    try:
        for s in tqdm(seeds, desc=desc, unit='scene'):
            rng = np.random.default_rng([1, s])
            for k in range(poses):
                try:
                    frame = r.frame(s, random_joints(rng), noise_seed=100 + k)
                except RuntimeError as exc:   # a few seeds cannot place every object on the table
                    tqdm.write(f'scene {s} skipped: {exc}')
                    break
                fp = frame_patches(frame, seed=s)
                for key in ('patches', 'labels', 'purity', 'fit_quality'):
                    parts[key].append(getattr(fp, key))
                parts['seed'].append(np.full(len(fp.labels), s))
    finally:
        r.close()
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}


def load_or_render(cache: Path, scenes: int, held_out: int, poses: int) -> dict[str, np.ndarray]:
    key = np.array([scenes, held_out, poses])
    if cache.is_file():
        data = dict(np.load(cache))
        if 'key' in data and np.array_equal(data['key'], key):
            print(f'train_classifier: patches from {cache}', flush=True)
            return data
    train = render_dataset(list(range(scenes)), poses, 'rendering training scenes')
    test = render_dataset(list(range(HELD_OUT_SEED, HELD_OUT_SEED + held_out)), poses,
                          'rendering held-out scenes')
    data = {f'{split}_{k}': v for split, d in (('train', train), ('test', test))
            for k, v in d.items()}
    data['key'] = key
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(cache, **data)
    return data


def average_precision(scores: np.ndarray, labels: np.ndarray) -> float:
    """Area under the precision-recall curve (step-wise, as sklearn's average_precision_score)."""
    order = np.argsort(-scores, kind='stable')
    y = labels[order].astype(float)
    tp = np.cumsum(y)
    precision = tp / np.arange(1, len(y) + 1)
    return float((precision * y).sum() / max(y.sum(), 1.0))


def _main(argv: list[str] | None = None) -> int:
    # the first paragraph of the module docstring, as one line
    ap = argparse.ArgumentParser(description=' '.join(__doc__.split('\n\n')[0].split()))
    ap.add_argument('--scenes', type=int, default=150, help='training scenes (seeds 0..N-1)')
    ap.add_argument('--held-out', type=int, default=30,
                    help=f'held-out scenes (seeds {HELD_OUT_SEED}..)')
    ap.add_argument('--poses', type=int, default=3, help='random head poses per scene')
    ap.add_argument('--epochs', type=int, default=15)
    ap.add_argument('--batch', type=int, default=64)
    ap.add_argument('--lr', type=float, default=3e-3)
    ap.add_argument('--threads', type=int, default=1, help='torch CPU threads')
    ap.add_argument('--cache', type=Path, default=DEFAULT_CACHE)
    ap.add_argument('--out', type=Path, default=None,
                    help='model file (default: the packaged model)')
    args = ap.parse_args(argv)

    import torch
    from tqdm import tqdm

    from cylinder_detector_node.core.classifier import DEFAULT_MODEL

    from .patch_data import MIN_PURITY
    from .patch_net import PatchNet, classifier_of, to_tensor

    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    t0 = time.monotonic()
    data = load_or_render(args.cache, args.scenes, args.held_out, args.poses)
    render_s = time.monotonic() - t0

    def split(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ok = data[f'{name}_purity'] >= MIN_PURITY   # clusters merging objects are ambiguous
        return (data[f'{name}_patches'][ok], data[f'{name}_labels'][ok],
                data[f'{name}_fit_quality'][ok])
    xtr, ytr, _ = split('train')
    xte, yte, qte = split('test')
    if len(xtr) == 0 or len(xte) == 0:
        print('train_classifier: no patches rendered (no offscreen OpenGL?)', file=sys.stderr)
        return 1
    print(f'train_classifier: {len(xtr)} training patches ({ytr.mean():.0%} cylinders), '
          f'{len(xte)} held-out ({yte.mean():.0%}); rendering {render_s:.0f} s', flush=True)
    mean = (xtr.reshape(-1, 3) / 255.0).mean(axis=0).astype(np.float32)
    std = (xtr.reshape(-1, 3) / 255.0).std(axis=0).astype(np.float32)
    net = PatchNet()
    x_all = np.concatenate([xtr, xtr[:, :, ::-1]])       # mirror augmentation (the thesis's), uint8
    y_all = torch.from_numpy(np.concatenate([ytr, ytr])).float()
    x_test = to_tensor(xte, mean, std)
    pos = float(y_all.mean())
    loss_fn = torch.nn.BCEWithLogitsLoss(pos_weight=torch.tensor((1 - pos) / max(pos, 1e-6)))
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=1e-4)
    steps = args.epochs * ((len(x_all) + args.batch - 1) // args.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=steps)
    gen = torch.Generator().manual_seed(0)

    def held_out() -> tuple[float, np.ndarray]:
        net.eval()
        with torch.inference_mode():
            p = torch.sigmoid(net(x_test)).numpy()
        net.train()
        return float(((p >= 0.5) == yte).mean()), p

    for epoch in range(args.epochs):
        perm = torch.randperm(len(x_all), generator=gen)
        total = 0.0
        bar = tqdm(range(0, len(perm), args.batch), desc=f'epoch {epoch + 1}/{args.epochs}',
                   unit='batch', leave=False)
        for i in bar:
            idx = perm[i:i + args.batch]
            xb = to_tensor(x_all[idx.numpy()], mean, std)
            # brightness / contrast jitter: the real camera is not the renderer
            xb = xb * (1 + 0.2 * (torch.rand(len(idx), 1, 1, 1, generator=gen) - 0.5)) \
                + 0.3 * (torch.rand(len(idx), 1, 1, 1, generator=gen) - 0.5)
            loss = loss_fn(net(xb), y_all[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach()) * len(idx)
        acc, _ = held_out()
        print(f'epoch {epoch + 1}: training loss {total / len(x_all):.4f}, '
              f'held-out accuracy {acc:.3f}', flush=True)
    acc, p = held_out()
    ap_cnn = average_precision(p, yte)
    ap_fit = average_precision(qte, yte)
    acc_fit = max(float(((qte >= t) == yte).mean()) for t in np.linspace(0, 1, 101))
    out = args.out or DEFAULT_MODEL
    out.parent.mkdir(parents=True, exist_ok=True)
    net.eval()
    clf = classifier_of(net, mean, std)
    clf.save(out, {
        'trained': datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'),
        'train_scenes': args.scenes, 'held_out_scenes': args.held_out,
        'held_out_first_seed': HELD_OUT_SEED,
        'poses_per_scene': args.poses, 'epochs': args.epochs, 'train_patches': int(len(xtr)),
        'held_out_patches': int(len(xte)), 'held_out_accuracy': round(acc, 4),
        'held_out_average_precision': round(ap_cnn, 4),
        'fit_quality_average_precision': round(ap_fit, 4),
        'fit_quality_best_accuracy': round(acc_fit, 4),
        'parameters': int(sum(p.numel() for p in net.parameters())),
    })
    print(f'train_classifier: held-out accuracy {acc:.3f} (Eq. 4.4 fit quality at its best '
          f'threshold: {acc_fit:.3f}); average precision {ap_cnn:.3f} vs {ap_fit:.3f}; saved {out} '
          f'({out.stat().st_size / 1024:.0f} KiB) in {time.monotonic() - t0:.0f} s', flush=True)
    return 0


main = main_needing_simulator(_main, 'train_cylinder_classifier')


if __name__ == '__main__':
    sys.exit(main())
