"""Window-mode training of train_classifier (`--window W --input-size S`): a small CNN that sees
only the W x W window around the fixation of a foveated render, resized to S x S
(core.recognition's window models; the views: training.window_views).

    train_foveation_classifier --window [160] [--input-size 96] --tabletop 480 --tabletop-val 40
        --search 100 --search-val 20 --epochs 14 --threads 2 --cache-dir /tmp/fovea_cache

Writes <out>/fovea_cnn.{pt,labels,json} (`--name` for another stem): the TorchScript model
((N, 3, S, S) normalised RGB -> (N, 8) scores: CLASSES and background), its labels, and the
preprocessing JSON (input_size, mean, std, window) with the training report (held-out figures
per source and class, confusion matrix, sizes, seeds, seconds, the command). `--render-only`
renders (and caches) the views and stops; `--shard i/n` renders every n-th chunk of scenes
only, so n processes can render one set together into --cache-dir.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from foveation_node.core.recognition import BACKGROUND_LABEL

if TYPE_CHECKING:
    import torch

DEFAULT_NAME = 'fovea_cnn'
WIDTHS = (24, 48, 64, 96, 128)
BACKGROUND_SHARE = 0.25
OBJECT_SOURCES = ('fixated', 'fixated_exact', 'anywhere', 'search_fixated', 'search_can')


def build_window_network(num_classes: int,
                         widths: tuple[int, ...] = WIDTHS) -> torch.nn.Module:
    """A small CNN for a window model's S x S input (S = 96: about 215 k parameters, 56 M
    multiply-adds per window).

    A 5x5 stride-2 first layer, four 3x3 conv blocks (BatchNorm, ReLU, 2x2 max-pooling between
    them), then 3x3 max pooling of the last map (not global: the network must tell an object at
    the window's centre, the fixation, from one off-centre, which is background here), dropout
    and one linear layer.
    """
    from torch import nn

    def block(i: int, o: int, k: int = 3, s: int = 1) -> list[nn.Module]:
        return [nn.Conv2d(i, o, k, s, k // 2, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True)]

    layers: list[nn.Module] = block(3, widths[0], 5, 2)
    for i, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
        layers += block(a, b)
        if i < len(widths) - 2:
            layers.append(nn.MaxPool2d(2))
    return nn.Sequential(*layers, nn.AdaptiveMaxPool2d(3), nn.Flatten(), nn.Dropout(0.3),
                         nn.Linear(widths[-1] * 9, num_classes))


def _in_memory_format(model: torch.nn.Module, fmt: torch.memory_format) -> torch.nn.Module:
    """model with its 4-d tensors in memory format fmt (channels_last trains faster on the CPU;
    the exported model is contiguous again)."""
    return model.to(memory_format=fmt)  # type: ignore[call-overload]   # torch's stubs lack it


def _sets(args: argparse.Namespace) -> tuple[Any, Any]:
    """(train, held-out) WindowSets: tabletop then visual_search scenes (module docstring)."""
    from foveation_node.training.train_classifier import (
        SEARCH_SEED0,
        SEARCH_VAL_SEED0,
        TABLETOP_SEED0,
        TABLETOP_VAL_SEED0,
    )
    from foveation_node.training.window_views import WindowSet, render_set

    shard = tuple(int(v) for v in args.shard.split('/'))
    w, s = args.window, args.input_size

    def one(scene: str, seed0: int, n: int, held_out: bool) -> Any:
        if n <= 0:
            return WindowSet.empty(s)
        return render_set(scene, seed0, n, held_out, w, s, args.cache_dir, (shard[0], shard[1]))

    train = WindowSet.concat([one('tabletop', TABLETOP_SEED0, args.tabletop, False),
                              one('visual_search', SEARCH_SEED0, args.search, False)], s)
    val = WindowSet.concat([one('tabletop', TABLETOP_VAL_SEED0, args.tabletop_val, True),
                            one('visual_search', SEARCH_VAL_SEED0, args.search_val, True)], s)
    return train, val


def scores(probs: np.ndarray, labels: np.ndarray, sources: np.ndarray,
           classes: tuple[str, ...]) -> dict[str, Any]:
    """Held-out figures: per object source top-1 (argmax over every class, background included)
    and the fraction rejected as background; per background source the fraction called
    background and where an object class still scores >= 0.3; per class top-1 of the fixated
    objects (tabletop and visual_search, exact fixations); confusion matrix of those and of
    every background view (last row)."""
    from foveation_node.training.window_views import SOURCES

    bg = len(classes)
    pred = probs.argmax(1) if len(probs) else np.zeros(0, int)
    r = lambda a: round(float(np.mean(a)), 4) if len(a) else None  # noqa: E731
    out: dict[str, Any] = {'objects': {}, 'background': {}}
    for code, name in enumerate(SOURCES):
        sel = sources == code
        if not sel.any():
            continue
        if name.startswith('background') or name == 'search_background':
            out['background'][name] = {'views': int(sel.sum()),
                                       'called_background': r(pred[sel] == bg),
                                       'object_score_at_least_0.3':
                                           r(probs[sel, :bg].max(axis=1) >= 0.3)}
        else:
            out['objects'][name] = {'views': int(sel.sum()), 'top1': r(pred[sel] == labels[sel]),
                                    'rejected_as_background': r(pred[sel] == bg)}
    is_bg = labels == bg
    out['background']['all'] = {'views': int(is_bg.sum()),
                                'called_background': r(pred[is_bg] == bg),
                                'object_score_at_least_0.3':
                                    r(probs[is_bg, :bg].max(axis=1) >= 0.3)
                                    if is_bg.any() else None}
    fixed = np.isin(sources, [SOURCES.index('fixated_exact'), SOURCES.index('search_fixated'),
                              SOURCES.index('fixated')])
    obj = fixed & ~is_bg
    out['fixated_objects'] = {'views': int(obj.sum()), 'top1': r(pred[obj] == labels[obj]),
                              'rejected_as_background': r(pred[obj] == bg),
                              'per_class_top1': {c: r(pred[obj & (labels == i)] == i)
                                                 for i, c in enumerate(classes)},
                              'per_class_views': {c: int((obj & (labels == i)).sum())
                                                  for i, c in enumerate(classes)}}
    rows = obj | is_bg
    confusion = np.zeros((bg + 1, bg + 1), int)
    np.add.at(confusion, (labels[rows], pred[rows]), 1)
    out['confusion_fixated_and_background_rows_true_cols_predicted'] = confusion.tolist()
    return out


def summary_line(sc: dict[str, Any]) -> str:
    f = sc['fixated_objects']
    parts = [f'fixated top-1 {f["top1"]} (rejected {f["rejected_as_background"]})']
    for name in ('anywhere', 'search_fixated', 'search_can'):
        if name in sc['objects']:
            parts.append(f'{name} {sc["objects"][name]["top1"]}')
    parts.append(f'background {sc["background"]["all"]["called_background"]}')
    return ', '.join(parts)


def train(args: argparse.Namespace, argv: list[str] | None) -> int:
    """train_classifier's window mode (module docstring)."""
    import sys
    import warnings

    import torch

    from foveation_node.training.object_views import CLASSES
    from foveation_node.training.train_classifier import (
        SEARCH_SEED0,
        SEARCH_VAL_SEED0,
        TABLETOP_SEED0,
        TABLETOP_VAL_SEED0,
        class_probabilities,
        one_cycle_adamw,
        train_epoch,
    )
    from foveation_node.training.window_views import (
        F0_RANGE,
        FIXATED_PER_OBJECT,
        FIXATION_JITTER_PX,
        HELD_OUT_F0,
        MIN_MARGIN_PX,
        POINT_JITTER_M,
        SOURCES,
    )

    command = 'train_foveation_classifier ' + shlex.join(sys.argv[1:] if argv is None else argv)
    labels_out = (*CLASSES, BACKGROUND_LABEL)
    background = len(CLASSES)
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    t0 = time.perf_counter()
    train_set, val_set = _sets(args)
    render_s = time.perf_counter() - t0
    print(f'{len(train_set.labels)} training and {len(val_set.labels)} held-out windows '
          f'({render_s:.0f} s)', flush=True)
    if args.render_only:
        return 0
    if not len(train_set.labels):
        raise SystemExit('no training views: give --tabletop / --search scenes')
    x_train, y_train = train_set.images, train_set.labels
    x_val, y_val, s_val = val_set.images, val_set.labels, val_set.sources
    n = len(y_train)

    if args.init is not None:
        pre = json.loads(args.init.with_suffix('.json').read_text(encoding='utf-8'))
        mean, std = np.asarray(pre['mean'], np.float32), np.asarray(pre['std'], np.float32)
    else:
        sample = x_train[::10].reshape(-1, 3).astype(np.float32)
        mean, std = sample.mean(axis=0) / 255.0, sample.std(axis=0) / 255.0
    scale = torch.tensor(1.0 / (255.0 * std), dtype=torch.float32).view(1, 3, 1, 1)
    shift = torch.tensor(-mean / std, dtype=torch.float32).view(1, 3, 1, 1)

    def to_input(batch: np.ndarray) -> torch.Tensor:
        x = torch.from_numpy(np.ascontiguousarray(batch)).permute(0, 3, 1, 2).float()
        return (x * scale + shift).contiguous(memory_format=torch.channels_last)

    model = build_window_network(len(labels_out))
    if args.init is not None:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', DeprecationWarning)
            model.load_state_dict(torch.jit.load(str(args.init), map_location='cpu').state_dict())
    model = _in_memory_format(model, torch.channels_last)   # 1.4x faster on the CPU

    # every object class equally likely; background views background_share of the draws
    share = args.background_share if args.background_share is not None else BACKGROUND_SHARE
    counts = np.bincount(y_train, minlength=len(labels_out)).astype(float)
    is_bg = y_train == background
    weights = np.where(is_bg, share / max(is_bg.sum(), 1),
                       (1.0 - share) / len(CLASSES) / np.maximum(counts[y_train], 1))
    weights /= weights.sum()
    steps = args.epochs * ((n + args.batch - 1) // args.batch)
    opt, sched = one_cycle_adamw(model, args.lr, steps)
    rng = np.random.default_rng(args.seed)

    def evaluate(xs: np.ndarray) -> np.ndarray:
        return class_probabilities(model, to_input, xs, len(labels_out), 256)

    t1 = time.perf_counter()
    model.train()
    history = []
    for epoch in range(args.epochs):
        order = rng.choice(n, n, p=weights)
        loss, top1 = train_epoch(model, opt, sched, x_train, y_train, order, args.batch,
                                 to_input, rng, f'epoch {epoch + 1}/{args.epochs}',
                                 gain=(0.75, 1.25), sort_batches=True)
        sc = scores(evaluate(x_val), y_val, s_val, CLASSES) if len(y_val) else None
        history.append({'epoch': epoch + 1, 'loss': round(loss, 4),
                        'train_top1': round(top1, 4),
                        'held_out': summary_line(sc) if sc else None})
        print(f'epoch {epoch + 1}: loss {loss:.3f}, train {top1:.3f}; '
              f'held-out {summary_line(sc) if sc else "-"} '
              f'({time.perf_counter() - t1:.0f} s)', flush=True)
    train_s = time.perf_counter() - t1
    held = scores(evaluate(x_val), y_val, s_val, CLASSES)

    model = _in_memory_format(model, torch.contiguous_format).eval()
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        scripted = torch.jit.script(model)
    args.out.mkdir(parents=True, exist_ok=True)
    name = args.name or DEFAULT_NAME
    model_path = args.out / f'{name}.pt'
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        scripted.save(str(model_path))
    (args.out / f'{name}.labels').write_text('\n'.join(labels_out) + '\n', encoding='utf-8')
    source_counts = {nm: {'train': int((train_set.sources == i).sum()),
                          'held_out': int((s_val == i).sum())}
                     for i, nm in enumerate(SOURCES)}
    report: dict[str, Any] = {
        'input_size': [args.input_size, args.input_size],
        'mean': [round(float(v), 5) for v in mean], 'std': [round(float(v), 5) for v in std],
        'window': args.window,
        'training': {
            'command': command,
            'classes': list(labels_out),
            'network': f'window CNN (training.window_training.build_window_network, widths '
                       f'{list(WIDTHS)}): 5x5/2 conv, 3x3 conv blocks with BatchNorm, ReLU and '
                       '2x2 max-pooling, 3x3 max pooling, dropout 0.3, linear',
            'parameters': sum(p.numel() for p in model.parameters()),
            'images': f'the {args.window}x{args.window} px window around the fixation of a '
                      'left-eye 640x480 render foveated (K 5) at it, resized to '
                      f'{args.input_size}x{args.input_size} (training.window_views); training '
                      f'f0 uniform in {F0_RANGE[0]:g}-{F0_RANGE[1]:g} px, held-out f0 '
                      f'{HELD_OUT_F0} (the node\'s)',
            'sources': 'fixated: the head fixating each object (vizzy_gaze solve_fixation of '
                       f'its centre in base_link, jittered {POINT_JITTER_M * 1000:g} mm per '
                       f'axis), {FIXATED_PER_OBJECT} windows at the principal point +- '
                       f'{FIXATION_JITTER_PX:g} px (held out: fixated_exact, the centre '
                       'exactly at the principal point); anywhere: objects seen in random head '
                       'poses, at their centre +- 12 px; background: fixations at least '
                       f'max(f0 / 2, {MIN_MARGIN_PX:g} px) from every object box (near: the '
                       'window holds an object off-centre; table: anywhere over the table; '
                       'away: poses anywhere within the joint limits; wall: the head tilted up '
                       'at the wall); visual_search: its cans fixated and seen, background in '
                       'poses anywhere. Labels: the object the ray through the fixation meets, '
                       'else the object fixated',
            'views': {'train': n, 'held_out': int(len(y_val)), 'by_source': source_counts,
                      'train_per_class': dict(zip(labels_out, map(int, counts), strict=True))},
            'tabletop_scenes': {'train': [TABLETOP_SEED0, TABLETOP_SEED0 + args.tabletop - 1],
                                'held_out': [TABLETOP_VAL_SEED0,
                                             TABLETOP_VAL_SEED0 + args.tabletop_val - 1]},
            'search_scenes': {'train': [SEARCH_SEED0, SEARCH_SEED0 + args.search - 1],
                              'held_out': [SEARCH_VAL_SEED0,
                                           SEARCH_VAL_SEED0 + args.search_val - 1]},
            'sampling': f'every object class equally likely, background views {share:g} of the '
                        'draws; horizontal flips, brightness and contrast jitter',
            'epochs': args.epochs, 'batch': args.batch, 'lr': args.lr, 'seed': args.seed,
            'optimiser': 'AdamW (weight decay 5e-4), one-cycle, label smoothing 0.05',
            'torch_threads': args.threads, 'render_s': round(render_s, 1),
            'train_s': round(train_s, 1), 'history': history,
            'held_out': held,
        },
    }
    if args.init is not None:
        report['training']['fine_tuned_from'] = args.init_note or args.init.name
    (args.out / f'{name}.json').write_text(json.dumps(report, indent=1) + '\n', encoding='utf-8')
    print(f'held-out: {summary_line(held)}; per class (fixated): ' + ', '.join(
        f'{c} {v}' for c, v in held['fixated_objects']['per_class_top1'].items()))
    print(f'wrote {model_path} ({os.path.getsize(model_path) / 1024:.0f} KiB), labels and '
          f'{name}.json; render {render_s:.0f} s, train {train_s:.0f} s')
    return 0


__all__ = ['BACKGROUND_SHARE', 'DEFAULT_NAME', 'WIDTHS', 'build_window_network', 'scores',
           'summary_line', 'train']
