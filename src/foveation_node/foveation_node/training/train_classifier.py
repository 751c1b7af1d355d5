"""Train the default recognition CNN of the foveation node on simulator renders.

    .venv/bin/python -m foveation_node.training.train_classifier [--train 3500] [--val 700]
        [--epochs 30]
        [--cache /tmp/views.npz] [--tabletop 200 --tabletop-val 40 --tabletop-cache /tmp/tt.npz]
        [--init foveation_node/models/foveation_cnn.pt]
    train_foveation_classifier ...                        # the console entry point

--tabletop N adds cluttered views (training.tabletop_views: N tabletop scenes not used by the
experiment, TABLETOP_POSES random head poses each): every unoccluded object in view gives one
image foveated (K = 5, f_0 uniform in 60-160 px) at its centre plus a small random offset,
labelled with the object under that point (the object the node's pass 2 has its fovea on);
classes are balanced by sampling, and the single-object and tabletop views are drawn half each.
--init fine-tunes a model (same architecture; its
preprocessing is kept) instead of starting from scratch.

Renders single-object views (training.object_views: the classes of our scenes, random pose,
colours, backdrop textures, table, lighting, depth and position in the image) with the left
eye camera at 640x480, resizes them to the network's 227x227 input and trains a small CNN on
the unfoveated images, as the thesis's ImageNet networks were trained on normal images. The
held-out views are rendered with another seed. Writes, into foveation_node/models/ (or --out):

  foveation_cnn.pt      TorchScript model: (N, 3, 227, 227) normalised RGB -> (N, C) scores
  foveation_cnn.labels  one class label per line
  foveation_cnn.json    preprocessing (input_size, mean, std) and the training report
                        (held-out accuracy, confusion matrix, sizes, seeds, seconds)

Rendering takes ~2 min and training ~17 min wall-clock on a loaded, shared 2-core VM (about
30 s per epoch); torch uses one thread unless --threads says otherwise. The packaged model:
the single-object model fine-tuned with `--tabletop 500 --tabletop-val 40 --epochs 16 --lr
2e-3 --threads 2` (4.7 min rendering, 10 min training).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from vizzy_vision.optional import main_needing_simulator

if TYPE_CHECKING:                   # torch is imported where it is used (slow to import)
    import torch

MODELS_DIR = Path(__file__).resolve().parents[1] / 'models'
MODEL_NAME = 'foveation_cnn'
INPUT_SIZE = (227, 227)
TABLETOP_SEED0 = 10000          # training scenes; held-out: TABLETOP_VAL_SEED0; experiment: 500
TABLETOP_VAL_SEED0 = 20000
TABLETOP_POSES = 3
FIXATION_JITTER_PX = 12.0
F0_RANGE = (60.0, 160.0)


def build_network(num_classes: int,
                  widths: tuple[int, int, int, int] = (16, 32, 64, 128)) -> torch.nn.Module:
    """A small all-convolutional CNN for 227x227 input (about 100 k parameters, 19 M multiply-adds).

    A 7x7 stride-4 first layer as AlexNet/CaffeNet (the thesis's smallest network), three 3x3
    layers with pooling, global max pooling and one linear layer. Max, not average, pooling:
    our objects cover a few percent of the image, and averaging drowned their features in the
    background's (a first run with average pooling stayed at chance for 5 epochs).
    """
    from torch import nn

    def block(i: int, o: int, k: int = 3, s: int = 1) -> list[nn.Module]:
        return [nn.Conv2d(i, o, k, s, k // 2, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True)]

    a, b, c, d = widths
    return nn.Sequential(*block(3, a, 7, 4), nn.MaxPool2d(3, 2, 1), *block(a, b), nn.MaxPool2d(2),
                         *block(b, c), nn.MaxPool2d(2, ceil_mode=True), *block(c, d),
                         nn.AdaptiveMaxPool2d(1), nn.Flatten(), nn.Dropout(0.2),
                         nn.Linear(d, num_classes))


def render_set(n: int, seed: int, desc: str) -> tuple[np.ndarray, np.ndarray]:
    """n views (balanced classes) resized to INPUT_SIZE: (n, h, w, 3) uint8 and (n,) labels."""
    from tqdm import tqdm

    from foveation_node.training.object_views import CLASSES, ObjectViews

    images = np.empty((n, INPUT_SIZE[1], INPUT_SIZE[0], 3), np.uint8)
    labels = np.arange(n) % len(CLASSES)
    rng = np.random.default_rng(seed)
    with ObjectViews(seed=seed) as views:
        for i in tqdm(range(n), desc=desc, unit='img'):
            view = views.render(int(labels[i]), rng)
            images[i] = cv2.resize(view.rgb, INPUT_SIZE, interpolation=cv2.INTER_AREA)
    return images, labels


def render_tabletop_set(scenes: int, seed0: int, desc: str) -> tuple[np.ndarray, np.ndarray]:
    """Foveated cluttered views (see the module docstring): (n, h, w, 3) uint8 and (n,) labels."""
    from tqdm import tqdm

    from foveation_node.core.foveation import Foveator
    from foveation_node.training.tabletop_views import TabletopViews, object_at, random_joints

    rng = np.random.default_rng(seed0)
    images: list[np.ndarray] = []
    labels: list[int] = []
    foveators: dict[int, Foveator] = {}
    with TabletopViews() as tv:
        for s in tqdm(range(seed0, seed0 + scenes), desc=desc, unit='scene'):
            for _ in range(TABLETOP_POSES):
                try:
                    view = tv.view(s, random_joints(rng))
                except RuntimeError:
                    break
                h, w = view.rgb.shape[:2]
                for o in view.objects:
                    if not o.visible:
                        continue
                    u = float(np.clip(o.centre[0] + rng.normal(0, FIXATION_JITTER_PX), 0, w - 1))
                    v = float(np.clip(o.centre[1] + rng.normal(0, FIXATION_JITTER_PX), 0, h - 1))
                    f0 = int(rng.uniform(*F0_RANGE))
                    if f0 not in foveators:
                        foveators[f0] = Foveator(w, h, 5, float(f0))
                    img = foveators[f0].foveate(view.rgb, (u, v))
                    images.append(cv2.resize(img, INPUT_SIZE, interpolation=cv2.INTER_AREA))
                    under = object_at(view.objects, u, v)
                    assert under is not None        # o is visible: never None
                    labels.append(under.label)
    return np.stack(images), np.asarray(labels, np.int64)


def _main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--train', type=int, default=3500, help='training views (rendered)')
    parser.add_argument('--val', type=int, default=700, help='held-out views (rendered)')
    parser.add_argument('--epochs', type=int, default=30)
    parser.add_argument('--batch', type=int, default=64)
    parser.add_argument('--lr', type=float, default=4e-3)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--threads', type=int, default=1, help='torch CPU threads')
    parser.add_argument('--out', type=Path, default=MODELS_DIR)
    parser.add_argument('--cache', type=Path, default=None,
                        help='.npz of the rendered views: loaded if it exists, else written')
    parser.add_argument('--tabletop', type=int, default=0,
                        help='tabletop scenes whose foveated object views join the training set')
    parser.add_argument('--tabletop-val', type=int, default=0, help='held-out tabletop scenes')
    parser.add_argument('--tabletop-cache', type=Path, default=None,
                        help='.npz of the tabletop views: loaded if it exists, else written')
    parser.add_argument('--init', type=Path, default=None,
                        help='TorchScript model to fine-tune (its .json preprocessing is kept)')
    args = parser.parse_args(argv)

    import torch
    from torch import nn
    from tqdm import tqdm

    from foveation_node.training.object_views import CLASSES

    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    t0 = time.perf_counter()
    from_cache = args.cache is not None and args.cache.exists()
    if from_cache:
        data = np.load(args.cache)
        x_train, y_train, x_val, y_val = (data[k] for k in ('x_train', 'y_train', 'x_val', 'y_val'))
        args.train, args.val = len(x_train), len(x_val)
        print(f'loaded {args.train} + {args.val} views from {args.cache}')
    else:
        x_train, y_train = render_set(args.train, 1000 + args.seed, 'render train')
        x_val, y_val = render_set(args.val, 2000 + args.seed, 'render held-out')
        if args.cache is not None:
            np.savez(args.cache, x_train=x_train, y_train=y_train, x_val=x_val, y_val=y_val)
    single_train = len(x_train)
    t_train = t_val = np.zeros((0, *INPUT_SIZE[::-1], 3), np.uint8)
    ty_train = ty_val = np.zeros(0, np.int64)
    if args.tabletop_cache is not None and args.tabletop_cache.exists():
        data = np.load(args.tabletop_cache)
        t_train, ty_train, t_val, ty_val = (data[k]
                                            for k in ('x_train', 'y_train', 'x_val', 'y_val'))
        print(f'loaded {len(t_train)} + {len(t_val)} tabletop views from {args.tabletop_cache}')
    elif args.tabletop > 0:
        t_train, ty_train = render_tabletop_set(args.tabletop, TABLETOP_SEED0, 'tabletop train')
        if args.tabletop_val > 0:
            t_val, ty_val = render_tabletop_set(args.tabletop_val, TABLETOP_VAL_SEED0,
                                                'tabletop held-out')
        if args.tabletop_cache is not None:
            np.savez(args.tabletop_cache, x_train=t_train, y_train=ty_train, x_val=t_val,
                     y_val=ty_val)
    if len(t_train):
        x_train = np.concatenate([x_train, t_train])
        y_train = np.concatenate([y_train, ty_train])
        args.train = len(x_train)
    render_s = time.perf_counter() - t0

    if args.init is not None:                      # keep the model's input normalisation
        pre = json.loads(args.init.with_suffix('.json').read_text(encoding='utf-8'))
        mean, std = np.asarray(pre['mean'], np.float32), np.asarray(pre['std'], np.float32)
    else:
        sample = x_train[::10].reshape(-1, 3).astype(np.float32)  # every 10th image is plenty
        mean = sample.mean(axis=0) / 255.0
        std = sample.std(axis=0) / 255.0
    scale = torch.tensor(1.0 / (255.0 * std), dtype=torch.float32).view(1, 3, 1, 1)
    shift = torch.tensor(-mean / std, dtype=torch.float32).view(1, 3, 1, 1)

    def to_input(batch: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(batch).permute(0, 3, 1, 2).float() * scale + shift

    model = build_network(len(CLASSES))
    if args.init is not None:
        import warnings
        with warnings.catch_warnings():       # torch >= 2.9 deprecates TorchScript
            warnings.simplefilter('ignore', DeprecationWarning)
            model.load_state_dict(torch.jit.load(str(args.init), map_location='cpu').state_dict())
    # sampling weights: every class equally likely within each source (the tabletop has more
    # cans than handles), and the single-object and tabletop views half of the draws each so
    # that the cluttered views do not crowd out the single-object ones
    source = np.arange(args.train) >= single_train
    weights = np.zeros(args.train)
    for sel in (~source, source):
        if sel.any():
            counts = np.bincount(y_train[sel], minlength=len(CLASSES)).astype(float)
            weights[sel] = 1.0 / counts[y_train[sel]]
            weights[sel] /= weights[sel].sum()
    weights /= weights.sum()
    steps = args.epochs * ((args.train + args.batch - 1) // args.batch)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=5e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=steps)
    rng = np.random.default_rng(args.seed)

    def evaluate(xs: np.ndarray = x_val, ys: np.ndarray = y_val) -> tuple[float, np.ndarray]:
        model.eval()
        pred = []
        with torch.inference_mode():
            for i in range(0, len(xs), 128):
                pred.append(model(to_input(xs[i:i + 128])).argmax(1).numpy())
        model.train()
        p = np.concatenate(pred) if pred else np.zeros(0, int)
        confusion = np.zeros((len(CLASSES), len(CLASSES)), int)
        np.add.at(confusion, (ys, p), 1)
        return float((p == ys).mean()) if len(ys) else float('nan'), confusion

    if args.init is not None:
        acc0, _ = evaluate()
        tacc0, _ = evaluate(t_val, ty_val)
        print(f'initial model: held-out top-1 {acc0:.3f}, tabletop held-out top-1 {tacc0:.3f}')

    t1 = time.perf_counter()
    model.train()
    for epoch in range(args.epochs):
        order = rng.choice(args.train, args.train, p=weights)       # class-balanced
        total, correct, loss_sum = 0, 0, 0.0
        bar = tqdm(range(0, args.train, args.batch), desc=f'epoch {epoch + 1}/{args.epochs}',
                   unit='batch')
        for i in bar:
            idx = order[i:i + args.batch]
            batch = x_train[idx]
            flip = rng.random(len(idx)) < 0.5                        # mirror images
            batch = np.where(flip[:, None, None, None], batch[:, :, ::-1], batch)
            x = to_input(batch)
            # brightness / contrast jitter, per image
            gain = torch.from_numpy(rng.uniform(0.8, 1.2, (len(idx), 1, 1, 1))).float()
            bias = torch.from_numpy(rng.normal(0.0, 0.15, (len(idx), 1, 1, 1))).float()
            x = x * gain + bias
            y = torch.from_numpy(y_train[idx])
            out = model(x)
            loss = nn.functional.cross_entropy(out, y, label_smoothing=0.05)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += len(idx)
            correct += int((out.argmax(1) == y).sum())
            loss_sum += float(loss) * len(idx)
            bar.set_postfix(loss=f'{loss_sum / total:.3f}', acc=f'{correct / total:.3f}')
        if (epoch + 1) % 5 == 0 or epoch + 1 == args.epochs:
            acc, _ = evaluate()
            tacc, _ = evaluate(t_val, ty_val)
            print(f'epoch {epoch + 1}: held-out top-1 accuracy {acc:.3f}, tabletop held-out '
                  f'{tacc:.3f}', flush=True)
    train_s = time.perf_counter() - t1
    accuracy, confusion = evaluate()
    t_accuracy, t_confusion = evaluate(t_val, ty_val)

    model.eval()
    scripted = torch.jit.script(model)
    args.out.mkdir(parents=True, exist_ok=True)
    model_path = args.out / f'{MODEL_NAME}.pt'
    scripted.save(str(model_path))
    (args.out / f'{MODEL_NAME}.labels').write_text('\n'.join(CLASSES) + '\n', encoding='utf-8')
    report: dict[str, Any] = {
        'input_size': list(INPUT_SIZE), 'mean': [round(float(v), 5) for v in mean],
        'std': [round(float(v), 5) for v in std],
        'training': {
            'classes': list(CLASSES), 'train_views': args.train, 'held_out_views': args.val,
            'epochs': args.epochs, 'batch': args.batch, 'lr': args.lr, 'seed': args.seed,
            'parameters': sum(p.numel() for p in model.parameters()),
            'held_out_top1_accuracy': round(accuracy, 4),
            'chance': round(1.0 / len(CLASSES), 4),
            'confusion_rows_true_cols_predicted': confusion.tolist(),
            'render_s': round(render_s, 1), 'views_from_cache': from_cache,
            'train_s': round(train_s, 1),
            'torch_threads': args.threads,
            'images': 'single-object views: unfoveated 640x480 left-eye renders resized to 227x227 '
                      '(training.object_views)',
        },
    }
    if args.init is not None:
        report['training']['fine_tuned_from'] = f'{args.init.name} (as packaged before)'
    if len(t_train):
        report['training'].update({
            'single_object_train_views': single_train,
            'tabletop_train_views': len(t_train), 'tabletop_held_out_views': len(t_val),
            'tabletop_scenes': [args.tabletop, args.tabletop_val],
            'tabletop_seeds': [TABLETOP_SEED0, TABLETOP_VAL_SEED0],
            'tabletop_poses_per_scene': TABLETOP_POSES,
            'tabletop_images': 'left-eye tabletop renders foveated (K 5, f0 60-160 px) at an '
                               'unoccluded object (+-12 px), labelled with the object there',
            'tabletop_held_out_top1_accuracy': round(t_accuracy, 4),
            'tabletop_confusion_rows_true_cols_predicted': t_confusion.tolist(),
            'sampling': 'class-balanced; single-object and tabletop views half each'})
    (args.out / f'{MODEL_NAME}.json').write_text(json.dumps(report, indent=1) + '\n',
                                                 encoding='utf-8')
    print(f'held-out top-1 accuracy {accuracy:.3f} on {args.val} views (chance '
          f'{1 / len(CLASSES):.3f}); per class: ' + ', '.join(
              f'{c} {confusion[i, i] / max(confusion[i].sum(), 1):.2f}'
              for i, c in enumerate(CLASSES)))
    if len(t_val):
        print(f'tabletop held-out top-1 accuracy {t_accuracy:.3f} on {len(t_val)} foveated views')
    print(f'wrote {model_path} ({os.path.getsize(model_path) / 1024:.0f} KiB), labels and '
          f'{MODEL_NAME}.json; render {render_s:.0f} s, train {train_s:.0f} s')
    return 0


main = main_needing_simulator(_main, 'train_foveation_classifier')


if __name__ == '__main__':
    sys.exit(main())
