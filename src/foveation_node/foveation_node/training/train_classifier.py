"""Train the default recognition CNN of the foveation node on simulator renders.

    .venv/bin/python -m foveation_node.training.train_classifier [--train 3500] [--val 700]
        [--epochs 30]
        [--cache /tmp/views.npz] [--tabletop 200 --tabletop-val 40 --tabletop-cache /tmp/tt.npz]
        [--init foveation_node/models/foveation_cnn.pt]
        [--background --search 150 --search-val 20 --background-share 0.2]
    train_foveation_classifier ...                        # the console entry point

--tabletop N adds cluttered views (training.tabletop_views: N tabletop scenes not used by the
experiment, TABLETOP_POSES random head poses each): every unoccluded object in view gives one
image foveated (K = 5, f_0 uniform in 60-160 px) at its centre plus a small random offset,
labelled with the object under that point (the object the node's pass 2 has its fovea on);
classes are balanced by sampling, and the single-object and tabletop views are drawn half each.
--init fine-tunes a model (same architecture; its
preprocessing is kept) instead of starting from scratch; a model with fewer outputs (the 7-class
one before the background class) keeps its weights, and the new last-layer rows start at zero.

--background adds the reject class BACKGROUND_LABEL (`background`, the last label): foveated
views (same K and f_0 range) at fixations on no object (training.background_views: at least
f_0 from every object's box), from the same tabletop scenes: in each of the object views' head
poses one fixation anywhere and one near the objects (f_0 to 2 f_0 from a box), and in
BACKGROUND_AWAY_POSES head poses anywhere within the joint limits (walls, floor, ceiling, up and
away) BACKGROUND_PER_AWAY fixations each; --search N adds visual_search scenes (textured
walls and floor; cans on stands, the stands background) from SEARCH_SEED0, SEARCH_POSES poses
anywhere, BACKGROUND_PER_AWAY fixations each, and in the same poses a view of every unoccluded
can foveated at it (labelled can: without them the network called the whole room background).
Held-out: the --tabletop-val scenes and --search-val visual_search scenes from
SEARCH_VAL_SEED0. The background views are drawn --background-share of the time (the
object views share the rest as before). Seeds 0-99 of both scenes are never used (an end-to-end
benchmark evaluates on them).

Renders single-object views (training.object_views: the classes of our scenes, random pose,
colours, backdrop textures, table, lighting, depth and position in the image) with the left
eye camera at 640x480, resizes them to the network's 227x227 input and trains a small CNN on
the unfoveated images, as the thesis's ImageNet networks were trained on normal images. The
held-out views are rendered with another seed. Writes, into foveation_node/models/ (or --out):

  foveation_cnn.pt      TorchScript model: (N, 3, 227, 227) normalised RGB -> (N, C) scores
  foveation_cnn.labels  one class label per line
  foveation_cnn.json    preprocessing (input_size, mean, std) and the training report
                        (held-out accuracy, confusion matrix, sizes, seeds, seconds)

--window [W] (default 160) trains a window model instead (training.window_training, views
from training.window_views): the network sees only the W x W window around the fixation of the
foveated render, resized to --input-size (96); it writes fovea_cnn.{pt,labels,json}.

Rendering takes ~2 min and training ~17 min wall-clock on a loaded, shared 2-core VM (about
30 s per epoch); torch uses one thread unless --threads says otherwise. The packaged model:
the single-object model fine-tuned with `--tabletop 500 --tabletop-val 40 --epochs 16 --lr
2e-3 --threads 2` (4.7 min rendering, 10 min training).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from foveation_node.core.recognition import BACKGROUND_LABEL
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
BACKGROUND_AWAY_POSES = 2       # per tabletop scene, anywhere within the joint limits
BACKGROUND_PER_AWAY = 2         # background fixations per pose looking anywhere
SEARCH_SEED0 = 10000            # visual_search scenes for background views; held-out from:
SEARCH_VAL_SEED0 = 20000
SEARCH_POSES = 4


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


class _Foveated:
    """Foveates a 640x480 render at (u, v) with a random f_0 of F0_RANGE (K = 5) and resizes it
    to INPUT_SIZE; one Foveator per whole-pixel f_0."""

    def __init__(self) -> None:
        from foveation_node.core.foveation import Foveator

        self._make = Foveator
        self._foveators: dict[tuple[int, int, int], Foveator] = {}

    def __call__(self, rgb: np.ndarray, u: float, v: float, rng: np.random.Generator,
                 f0: int | None = None) -> np.ndarray:
        """rgb foveated at (u, v), f_0 drawn from rng unless given, resized to INPUT_SIZE."""
        h, w = rgb.shape[:2]
        if f0 is None:
            f0 = int(rng.uniform(*F0_RANGE))
        key = (w, h, f0)
        if key not in self._foveators:
            self._foveators[key] = self._make(w, h, 5, float(f0))
        img = self._foveators[key].foveate(rgb, (u, v))
        return cv2.resize(img, INPUT_SIZE, interpolation=cv2.INTER_AREA)


def render_tabletop_set(scenes: int, seed0: int, desc: str, background: bool = False
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Foveated cluttered views (see the module docstring): (n, h, w, 3) uint8 and (n,) labels.

    background: also the background views of these scenes (label len(CLASSES)), after the
    object views; they draw from their own random stream, so the object views are the same
    with or without them."""
    from tqdm import tqdm

    from foveation_node.training.background_views import away_joints
    from foveation_node.training.object_views import CLASSES
    from foveation_node.training.tabletop_views import TabletopViews, object_at, random_joints

    rng = np.random.default_rng(seed0)
    bg_rng = np.random.default_rng([seed0, 7])
    images: list[np.ndarray] = []
    labels: list[int] = []
    bg_images: list[np.ndarray] = []
    foveated = _Foveated()
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
                    images.append(foveated(view.rgb, u, v, rng))
                    under = object_at(view.objects, u, v)
                    assert under is not None        # o is visible: never None
                    labels.append(under.label)
                if background:                      # one anywhere, one near the objects
                    bg_images += background_views(view, bg_rng, foveated, 1, near=True)
                    bg_images += background_views(view, bg_rng, foveated, 1)
            if not background:
                continue
            for _ in range(BACKGROUND_AWAY_POSES):
                try:
                    view = tv.view(s, away_joints(bg_rng))
                except RuntimeError:
                    break
                bg_images += background_views(view, bg_rng, foveated, BACKGROUND_PER_AWAY)
    labels += [len(CLASSES)] * len(bg_images)
    return np.stack(images + bg_images), np.asarray(labels, np.int64)


def background_views(view: Any, rng: np.random.Generator, foveated: _Foveated, n: int,
                     near: bool = False) -> list[np.ndarray]:
    """Up to n background views of a TableView: f_0 drawn from F0_RANGE, fixations at least
    margin_for(f_0) from every object box (near: also less than twice that)."""
    from foveation_node.training.background_views import background_fixations, margin_for

    f0 = int(rng.uniform(*F0_RANGE))
    margin = margin_for(f0)
    h, w = view.rgb.shape[:2]
    fix = background_fixations(view.extents, w, h, rng, n, margin,
                               2 * margin if near else math.inf)
    return [foveated(view.rgb, u, v, rng, f0) for u, v in fix]


def render_search_set(scenes: int, seed0: int, desc: str) -> tuple[np.ndarray, np.ndarray]:
    """Views of visual_search scenes (see the module docstring): the background views, then one
    view of every unoccluded can in the same poses foveated at its centre (+-12 px, as the
    tabletop's object views; without them the network learnt "this room is background" and
    rejected its cans). (n, h, w, 3) uint8 and (n,) labels."""
    from tqdm import tqdm

    from foveation_node.training.background_views import away_joints
    from foveation_node.training.object_views import CLASSES
    from foveation_node.training.tabletop_views import TabletopViews, object_at
    from vizzy_sim_bridge.core.scenes import visual_search

    rng = np.random.default_rng([seed0, 8])
    obj_rng = np.random.default_rng([seed0, 9])
    images: list[np.ndarray] = []
    objects: list[np.ndarray] = []
    labels: list[int] = []
    foveated = _Foveated()
    with TabletopViews(scene=visual_search) as tv:
        for s in tqdm(range(seed0, seed0 + scenes), desc=desc, unit='scene'):
            for _ in range(SEARCH_POSES):
                view = tv.view(s, away_joints(rng))
                images += background_views(view, rng, foveated, BACKGROUND_PER_AWAY)
                h, w = view.rgb.shape[:2]
                for o in view.objects:
                    if not o.visible:
                        continue
                    u = float(np.clip(o.centre[0] + obj_rng.normal(0, FIXATION_JITTER_PX), 0,
                                      w - 1))
                    v = float(np.clip(o.centre[1] + obj_rng.normal(0, FIXATION_JITTER_PX), 0,
                                      h - 1))
                    objects.append(foveated(view.rgb, u, v, obj_rng))
                    under = object_at(view.objects, u, v)
                    assert under is not None                 # o is visible: never None
                    labels.append(under.label)
    all_images = images + objects
    return (np.stack(all_images) if all_images
            else np.zeros((0, *INPUT_SIZE[::-1], 3), np.uint8),
            np.asarray([len(CLASSES)] * len(images) + labels, np.int64))


def one_cycle_adamw(model: torch.nn.Module, lr: float, steps: int) -> tuple[Any, Any]:
    """The trainers' optimiser (AdamW, weight decay 5e-4) and its one-cycle schedule over
    `steps` batches."""
    import torch
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=5e-4)
    return opt, torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=steps)


def class_probabilities(model: torch.nn.Module, to_input: Any, xs: np.ndarray,
                        num_classes: int, batch_size: int = 128) -> np.ndarray:
    """(N, num_classes) softmax probabilities of uint8 views, in batches, in eval mode (the
    model is left in training mode)."""
    import torch
    model.eval()
    out = [np.zeros((0, num_classes), np.float32)]
    with torch.inference_mode():
        for i in range(0, len(xs), batch_size):
            out.append(torch.softmax(model(to_input(xs[i:i + batch_size])), 1).numpy())
    model.train()
    return np.concatenate(out)


def train_epoch(model: torch.nn.Module, opt: Any, sched: Any, x_train: np.ndarray,
                y_train: np.ndarray, order: np.ndarray, batch_size: int,
                to_input: Any, rng: np.random.Generator, desc: str,
                gain: tuple[float, float] = (0.8, 1.2),
                sort_batches: bool = False) -> tuple[float, float]:
    """One epoch over x_train[order] in batches: mirror images at random, brightness (gain
    uniform in `gain`) and offset (N(0, 0.15)) jitter per image, cross-entropy with label
    smoothing 0.05, one optimiser and scheduler step per batch. sort_batches: read each batch's
    rows in index order (kinder to a large memory-mapped x_train). Returns (mean loss, training
    top-1)."""
    import torch
    from torch import nn
    from tqdm import tqdm

    total, correct, loss_sum = 0, 0, 0.0
    bar = tqdm(range(0, len(order), batch_size), desc=desc, unit='batch', mininterval=10)
    for i in bar:
        idx = np.sort(order[i:i + batch_size]) if sort_batches else order[i:i + batch_size]
        batch = x_train[idx]
        flip = rng.random(len(idx)) < 0.5                        # mirror images
        batch = np.where(flip[:, None, None, None], batch[:, :, ::-1], batch)
        x = to_input(batch)
        # brightness / contrast jitter, per image
        g = torch.from_numpy(rng.uniform(gain[0], gain[1], (len(idx), 1, 1, 1))).float()
        b = torch.from_numpy(rng.normal(0.0, 0.15, (len(idx), 1, 1, 1))).float()
        x = x * g + b
        y = torch.from_numpy(y_train[idx])
        out = model(x)
        loss = nn.functional.cross_entropy(out, y, label_smoothing=0.05)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        total += len(idx)
        correct += int((out.argmax(1) == y).sum())
        loss_sum += loss.item() * len(idx)
        bar.set_postfix(loss=f'{loss_sum / total:.3f}', acc=f'{correct / total:.3f}')
    return loss_sum / max(total, 1), correct / max(total, 1)


def load_grown(model: torch.nn.Module, state: dict[str, torch.Tensor]) -> None:
    """Load state (same architecture) into model; a tensor with fewer rows than the model's
    (the last layer of a model with fewer classes) fills the first rows and the new rows
    start at zero (a new class begins with score 0 everywhere)."""
    import torch

    own = model.state_dict()
    for name, value in state.items():
        if name in own and own[name].shape != value.shape:
            if own[name].shape[1:] != value.shape[1:] or value.shape[0] > own[name].shape[0]:
                raise ValueError(f'{name}: cannot grow {tuple(value.shape)} into '
                                 f'{tuple(own[name].shape)}')
            grown = torch.zeros_like(own[name])
            grown[:value.shape[0]] = value
            state = {**state, name: grown}
    model.load_state_dict(state)


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
    parser.add_argument('--init-note', default=None,
                        help='what --init is, for the report (default: its file name)')
    parser.add_argument('--background', action='store_true',
                        help=f'add the reject class {BACKGROUND_LABEL!r}: views on no object of '
                             'the --tabletop scenes (and of --search scenes)')
    parser.add_argument('--search', type=int, default=0,
                        help='visual_search scenes whose background views join the training set')
    parser.add_argument('--search-val', type=int, default=0,
                        help='held-out visual_search scenes (background views)')
    parser.add_argument('--search-cache', type=Path, default=None,
                        help='.npz of the visual_search background views (as --tabletop-cache)')
    parser.add_argument('--background-share', type=float, default=None,
                        help='fraction of the draws that are background views (default 0.2; '
                             'window mode 0.25)')
    parser.add_argument('--window', type=int, nargs='?', const=160, default=0,
                        help='window mode (training.window_training): the network sees the '
                             'W x W px window around the fixation (--window alone: 160); 0 '
                             '(default): the whole frame')
    parser.add_argument('--input-size', type=int, default=96,
                        help='window mode: the network input side [px] the window is resized to')
    parser.add_argument('--cache-dir', type=Path, default=None,
                        help='window mode: folder of the rendered views, one .npz per chunk of '
                             'scenes (loaded if there, else written)')
    parser.add_argument('--shard', default='0/1',
                        help='window mode: i/n renders only every n-th chunk (from the i-th)')
    parser.add_argument('--render-only', action='store_true',
                        help='window mode: render (and cache) the views, do not train')
    parser.add_argument('--name', default=None,
                        help='window mode: file stem of the model (default fovea_cnn)')
    args = parser.parse_args(argv)
    if args.window:
        if args.window < 8 or args.input_size < 8:
            parser.error('--window and --input-size must be at least 8 px')
        if args.background_share is not None and not 0.0 < args.background_share < 1.0:
            parser.error('--background-share must be in (0, 1)')
        i, _, n = args.shard.partition('/')
        if not (i.isdigit() and n.isdigit() and int(i) < int(n)):
            parser.error(f'--shard must be i/n with 0 <= i < n, got {args.shard}')
        from foveation_node.training.window_training import train as train_window
        return train_window(args, argv)
    if args.background_share is None:
        args.background_share = 0.2
    if args.background and args.tabletop <= 0 and args.tabletop_cache is None:
        parser.error('--background needs --tabletop scenes (or a --tabletop-cache)')
    if not 0.0 < args.background_share < 1.0:
        parser.error('--background-share must be in (0, 1)')

    import torch

    from foveation_node.training.object_views import CLASSES

    labels_out = (*CLASSES, BACKGROUND_LABEL) if args.background else CLASSES
    background = len(CLASSES)                     # the background class's index (if any)
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
        t_train, ty_train = render_tabletop_set(args.tabletop, TABLETOP_SEED0, 'tabletop train',
                                                args.background)
        if args.tabletop_val > 0:
            t_val, ty_val = render_tabletop_set(args.tabletop_val, TABLETOP_VAL_SEED0,
                                                'tabletop held-out', args.background)
        if args.tabletop_cache is not None:
            np.savez(args.tabletop_cache, x_train=t_train, y_train=ty_train, x_val=t_val,
                     y_val=ty_val)
    if args.background and not (ty_train == background).any():
        raise SystemExit(f'{args.tabletop_cache} holds no background views: render it anew '
                         'with --background (another --tabletop-cache path)')
    if not args.background:                        # a cache with background, used without it
        t_train, ty_train = t_train[ty_train != background], ty_train[ty_train != background]
        t_val, ty_val = t_val[ty_val != background], ty_val[ty_val != background]
    s_train = s_val = np.zeros((0, *INPUT_SIZE[::-1], 3), np.uint8)
    sy_train = sy_val = np.zeros(0, np.int64)
    if args.background and args.search_cache is not None and args.search_cache.exists():
        data = np.load(args.search_cache)
        s_train, sy_train, s_val, sy_val = (data[k]
                                            for k in ('x_train', 'y_train', 'x_val', 'y_val'))
        print(f'loaded {len(s_train)} + {len(s_val)} visual_search background views from '
              f'{args.search_cache}')
    elif args.background and (args.search > 0 or args.search_val > 0):
        if args.search > 0:
            s_train, sy_train = render_search_set(args.search, SEARCH_SEED0, 'search train')
        if args.search_val > 0:
            s_val, sy_val = render_search_set(args.search_val, SEARCH_VAL_SEED0,
                                              'search held-out')
        if args.search_cache is not None:
            np.savez(args.search_cache, x_train=s_train, y_train=sy_train, x_val=s_val,
                     y_val=sy_val)
    tabletop_objects_train = int((ty_train != background).sum())
    tabletop_objects_val = int((ty_val != background).sum())
    n_table_val = len(t_val)                      # held-out: tabletop views, then search views
    bg_counts = {'tabletop_train': int((ty_train == background).sum()),
                 'tabletop_held_out': int((ty_val == background).sum()),
                 'search_train': int((sy_train == background).sum()),
                 'search_held_out': int((sy_val == background).sum())}
    search_objects = {'train': int((sy_train != background).sum()),
                      'held_out': int((sy_val != background).sum())}
    t_train, ty_train = np.concatenate([t_train, s_train]), np.concatenate([ty_train, sy_train])
    t_val, ty_val = np.concatenate([t_val, s_val]), np.concatenate([ty_val, sy_val])
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

    model = build_network(len(labels_out))
    if args.init is not None:
        import warnings
        with warnings.catch_warnings():       # torch >= 2.9 deprecates TorchScript
            warnings.simplefilter('ignore', DeprecationWarning)
            state = torch.jit.load(str(args.init), map_location='cpu').state_dict()
        load_grown(model, state)
    # sampling weights: every class equally likely within each source (the tabletop has more
    # cans than handles), and the single-object and tabletop views half of the object draws
    # each so that the cluttered views do not crowd out the single-object ones; background
    # views (if any) args.background_share of all draws
    source = np.arange(args.train) >= single_train
    is_bg = y_train == background if args.background else np.zeros(args.train, bool)
    weights = np.zeros(args.train)
    for sel in (~source, source & ~is_bg):
        if sel.any():
            counts = np.bincount(y_train[sel], minlength=len(labels_out)).astype(float)
            weights[sel] = 1.0 / counts[y_train[sel]]
            weights[sel] /= weights[sel].sum()
    if is_bg.any():
        weights /= weights.sum()
        weights *= 1.0 - args.background_share
        weights[is_bg] = args.background_share / is_bg.sum()
    weights /= weights.sum()
    steps = args.epochs * ((args.train + args.batch - 1) // args.batch)
    opt, sched = one_cycle_adamw(model, args.lr, steps)
    rng = np.random.default_rng(args.seed)

    def evaluate(xs: np.ndarray) -> np.ndarray:
        """(N, C) class probabilities of uint8 views."""
        return class_probabilities(model, to_input, xs, len(labels_out), 128)

    def scores(probs: np.ndarray, ys: np.ndarray) -> dict[str, Any]:
        """Top-1 accuracy and background-rejection rate of the object views, the background
        views' recall and how often an object class still scores >= 0.3 there; confusion."""
        pred = probs.argmax(1) if len(probs) else np.zeros(0, int)
        obj = ys != background if args.background else np.ones(len(ys), bool)
        confusion = np.zeros((len(labels_out), len(labels_out)), int)
        np.add.at(confusion, (ys, pred), 1)
        mean = lambda a: round(float(a.mean()), 4) if len(a) else float('nan')  # noqa: E731
        out: dict[str, Any] = {'accuracy': mean(pred[obj] == ys[obj]), 'confusion': confusion}
        if args.background:
            objects = probs[:, :len(CLASSES)]
            out['rejected'] = mean(pred[obj] == background)
            out['background_recall'] = mean(pred[~obj] == background)
            out['background_object_at_0.3'] = mean(objects[~obj].max(axis=1) >= 0.3)
        return out

    def line(name: str, sc: dict[str, Any]) -> str:
        text = f'{name} top-1 {sc["accuracy"]:.3f}'
        if args.background:
            text += f' (rejected {sc["rejected"]:.3f})'
            if not np.isnan(sc['background_recall']):
                text += (f', background recall {sc["background_recall"]:.3f}, object >= 0.3 '
                         f'on background {sc["background_object_at_0.3"]:.3f}')
        return text

    if args.init is not None:
        probs = evaluate(t_val)
        print('initial model: ' + line('held-out', scores(evaluate(x_val), y_val)) + '; '
              + line('tabletop held-out', scores(probs[:n_table_val], ty_val[:n_table_val]))
              + '; ' + line('search held-out', scores(probs[n_table_val:],
                                                      ty_val[n_table_val:])), flush=True)

    t1 = time.perf_counter()
    model.train()
    for epoch in range(args.epochs):
        order = rng.choice(args.train, args.train, p=weights)       # class-balanced
        train_epoch(model, opt, sched, x_train, y_train, order, args.batch, to_input, rng,
                    f'epoch {epoch + 1}/{args.epochs}')
        if (epoch + 1) % 5 == 0 or epoch + 1 == args.epochs:
            probs = evaluate(t_val)
            print(f'epoch {epoch + 1}: ' + line('held-out', scores(evaluate(x_val), y_val))
                  + '; ' + line('tabletop held-out', scores(probs[:n_table_val],
                                                            ty_val[:n_table_val]))
                  + '; ' + line('search held-out', scores(probs[n_table_val:],
                                                          ty_val[n_table_val:])), flush=True)
    train_s = time.perf_counter() - t1
    single = scores(evaluate(x_val), y_val)
    t_probs = evaluate(t_val)
    every = scores(t_probs, ty_val)                           # tabletop and search views
    table = scores(t_probs[:n_table_val], ty_val[:n_table_val])
    search = scores(t_probs[n_table_val:], ty_val[n_table_val:])
    accuracy, confusion = single['accuracy'], single['confusion']

    model.eval()
    scripted = torch.jit.script(model)
    args.out.mkdir(parents=True, exist_ok=True)
    model_path = args.out / f'{MODEL_NAME}.pt'
    scripted.save(str(model_path))
    (args.out / f'{MODEL_NAME}.labels').write_text('\n'.join(labels_out) + '\n',
                                                   encoding='utf-8')
    report: dict[str, Any] = {
        'input_size': list(INPUT_SIZE), 'mean': [round(float(v), 5) for v in mean],
        'std': [round(float(v), 5) for v in std],
        'training': {
            'classes': list(labels_out), 'train_views': args.train, 'held_out_views': args.val,
            'epochs': args.epochs, 'batch': args.batch, 'lr': args.lr, 'seed': args.seed,
            'parameters': sum(p.numel() for p in model.parameters()),
            'held_out_top1_accuracy': accuracy,
            'chance': round(1.0 / len(CLASSES), 4),
            'confusion_rows_true_cols_predicted': confusion.tolist(),
            'render_s': round(render_s, 1), 'views_from_cache': from_cache,
            'train_s': round(train_s, 1),
            'torch_threads': args.threads,
            'images': 'single-object views: unfoveated 640x480 left-eye renders resized to 227x227 '
                      '(training.object_views)',
        },
    }
    if args.background:
        report['training']['held_out_rejected_as_background'] = single['rejected']
    if args.init is not None:
        report['training']['fine_tuned_from'] = args.init_note or args.init.name
    if len(t_train):
        report['training'].update({
            'single_object_train_views': single_train,
            'tabletop_train_views': tabletop_objects_train,
            'tabletop_held_out_views': tabletop_objects_val,
            'tabletop_scenes': [args.tabletop, args.tabletop_val],
            'tabletop_seeds': [TABLETOP_SEED0, TABLETOP_VAL_SEED0],
            'tabletop_poses_per_scene': TABLETOP_POSES,
            'tabletop_images': 'left-eye tabletop renders foveated (K 5, f0 60-160 px) at an '
                               'unoccluded object (+-12 px), labelled with the object there',
            'tabletop_held_out_top1_accuracy': table['accuracy'],
            'tabletop_confusion_rows_true_cols_predicted': table['confusion'].tolist(),
            'sampling': 'class-balanced; single-object and tabletop views half each'})
    if args.background:
        from foveation_node.training.background_views import MARGIN_PX

        report['training'].update({
            'tabletop_held_out_rejected_as_background': table['rejected'],
            'tabletop_confusion_rows_true_cols_predicted_includes': 'background views (last row)',
            'background': {
                'label': BACKGROUND_LABEL, 'index': background,
                'views': bg_counts,
                'images': 'left-eye renders foveated (K 5, f0 60-160 px) at a fixation at least '
                          f'f0 (>= {MARGIN_PX:g} px) from every object box: tabletop scenes (the '
                          'object views\' poses: one fixation anywhere, one f0-2 f0 from a box; '
                          f'{BACKGROUND_AWAY_POSES} '
                          f'poses anywhere within the joint limits, {BACKGROUND_PER_AWAY} '
                          f'fixations each) and visual_search scenes ({SEARCH_POSES} poses '
                          f'anywhere, {BACKGROUND_PER_AWAY} fixations each; in the same poses '
                          'every unoccluded can, foveated at it (+-12 px), is a can view)',
                'search_scenes': [args.search, args.search_val],
                'search_seeds': [SEARCH_SEED0, SEARCH_VAL_SEED0],
                'margin': f'f0, at least {MARGIN_PX:g} px',
                'share_of_draws': args.background_share,
                'held_out_recall': every['background_recall'],
                'held_out_object_score_at_least_0.3': every['background_object_at_0.3'],
                'held_out_recall_tabletop': table['background_recall'],
                'held_out_recall_search': search['background_recall']},
            'search_can_views': search_objects,
            'search_held_out_can_top1_accuracy': search['accuracy'],
            'search_held_out_can_rejected_as_background': search['rejected'],
            'sampling': f'class-balanced; background views {args.background_share:g} of the '
                        'draws, single-object and tabletop object views half each of the rest'})
    (args.out / f'{MODEL_NAME}.json').write_text(json.dumps(report, indent=1) + '\n',
                                                 encoding='utf-8')
    print(f'held-out top-1 accuracy {accuracy:.3f} on {args.val} views (chance '
          f'{1 / len(CLASSES):.3f}); per class: ' + ', '.join(
              f'{c} {confusion[i, i] / max(confusion[i].sum(), 1):.2f}'
              for i, c in enumerate(CLASSES)))
    if len(t_val):
        print(line(f'tabletop held-out ({n_table_val} foveated views)', table))
    if len(t_val) > n_table_val:
        print(line(f'visual_search held-out ({len(t_val) - n_table_val} foveated views)',
                   search))
    print(f'wrote {model_path} ({os.path.getsize(model_path) / 1024:.0f} KiB), labels and '
          f'{MODEL_NAME}.json; render {render_s:.0f} s, train {train_s:.0f} s')
    return 0


main = main_needing_simulator(_main, 'train_foveation_classifier')


if __name__ == '__main__':
    sys.exit(main())
