#!/usr/bin/env python3
"""Thesis Fig. 2.6: energy and information of the foveated image as a function of the fovea size.

From the formulas of section 2.3.1 (Eqs. 2.5-2.18, `foveation_node.core.information`) for the
thesis's setting: 227x227 images, sigma_1 = 1, K = 5 Laplacian levels, fixation at the centre,
f_0 in [0.1, 227]; a flat spectrum at the full 8-bit scale (per-pixel power 255^2). Ratios are
against the unfoveated image analysed the same way. Measured on images with the same equations
applied to their actual full-resolution decomposition: white noise (the formulas' assumption)
and 1/f noise (natural-image-like spectra), several seeds each.

Also: the dependence on image size (N = 64 ... 1024; the ratios depend on f_0 / N), on the signal
power (the information ratio does, the energy ratio does not), and the curve of the scale space
the real-time pyramid realises (sigma_1 = sqrt(8/3)).

Writes experiments/results/fovea_information.png and .json.

    .venv/bin/python experiments/fovea_information.py [--seeds 4] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'foveation_node'))
from foveation_node.core.foveation import PYRAMID_SIGMA_1, Foveator  # noqa: E402
from foveation_node.core.information import (  # noqa: E402
    FULL_SCALE_POWER,
    measured_information,
    predicted_information,
)
from foveation_node.core.synthetic import pink_noise, to_uint8, white_noise  # noqa: E402

sys.path.insert(0, str(ROOT / 'experiments'))
from protocol import cpu_seconds, protocol  # noqa: E402


def protocol_of(result: dict, cpu_s: float | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields."""
    st = result['setting']
    return protocol(
        data=f"the section 2.3.1 formulas (Eqs. 2.5-2.18) for {st['N']}x{st['N']} images, "
             f"sigma_1 = {st['sigma_1']}, K = {st['levels']} levels; measured on "
             f"{st['seeds_per_kind']} white-noise and {st['seeds_per_kind']} 1/f-noise images",
        repetitions={'formula curve': 1, 'measured images per kind': st['seeds_per_kind']},
        thesis_repetitions={'formula curve': 1},
        models='none (analytic)',
        differs_from_thesis=['the thesis does not state the signal power or the reference of '
                             'its ratios: here per-pixel power 255^2 and ratios against the '
                             'unfoveated image analysed with the same equations'],
        cpu_s=cpu_s)

N = 227
SIGMA_1 = 1.0
LEVELS = 5
THESIS = {'information_ratio_at_f0_100': 0.94, 'saturation_f0': 120.0}
SIZE_POINTS = 120


def rounded(value: object, digits: int = 5) -> object:
    """Floats rounded for a compact JSON."""
    if isinstance(value, float):
        return round(value, digits)
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, list):
        return [rounded(v, digits) for v in value]
    return value


def curve(size: int, f0s: np.ndarray, sigma_1: float = SIGMA_1, levels: int = LEVELS,
          power: float = FULL_SCALE_POWER) -> dict[str, np.ndarray]:
    infos = [predicted_information(size, size, float(f), sigma_1, levels, power) for f in f0s]
    return {'energy_ratio': np.array([i.energy_ratio for i in infos]),
            'energy_ratio_parseval': np.array([i.energy_ratio_parseval for i in infos]),
            'information_ratio': np.array([i.information_ratio for i in infos]),
            'bits_foveated': np.array([i.bits_foveated for i in infos]),
            'bits_original': np.array([i.bits_original for i in infos])}


def crossing(f0s: np.ndarray, values: np.ndarray, level: float) -> float | None:
    """Smallest f_0 where the (increasing) curve reaches `level`, linearly interpolated."""
    above = np.flatnonzero(values >= level)
    if not above.size:
        return None
    i = int(above[0])
    if i == 0:
        return float(f0s[0])
    t = (level - values[i - 1]) / (values[i] - values[i - 1])
    return float(f0s[i - 1] + t * (f0s[i] - f0s[i - 1]))


def measure(kind: str, f0s: np.ndarray, seeds: int) -> dict[str, list[float]]:
    from tqdm import tqdm

    centre = ((N - 1) / 2.0, (N - 1) / 2.0)
    energy = np.zeros((seeds, f0s.size))
    bits = np.zeros((seeds, f0s.size))
    with tqdm(total=seeds * f0s.size, desc=f'measuring on {kind}', unit='image') as bar:
        for s in range(seeds):
            if kind == 'white noise':
                image = white_noise(N, N, channels=1, std=255.0, mean=0.0, seed=100 + s)
            else:
                image = pink_noise(N, N, channels=3, seed=200 + s)   # 8-bit-like: std 40
            for j, f0 in enumerate(f0s):
                info = measured_information(image, centre, float(f0), SIGMA_1, LEVELS)
                energy[s, j], bits[s, j] = info.energy_ratio, info.information_ratio
                bar.update()
    return {'energy_ratio': energy.mean(0).tolist(), 'energy_ratio_std': energy.std(0).tolist(),
            'information_ratio': bits.mean(0).tolist(),
            'information_ratio_std': bits.std(0).tolist()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', type=int, default=4, help='images per kind for the measurement')
    ap.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    f0s = np.unique(np.concatenate([np.geomspace(0.1, 1.0, 10), np.arange(1.0, 228.0, 1.0)]))
    thesis = curve(N, f0s)
    four_levels = curve(N, f0s, levels=4)
    pyramid = curve(N, f0s, sigma_1=PYRAMID_SIGMA_1)
    sizes = (64, 128, 227, 480, 1024)
    by_size = {n: curve(n, np.geomspace(0.1, 2.0 * n, SIZE_POINTS)) for n in sizes}
    powers = {'255^2': FULL_SCALE_POWER, '64^2': 64.0 ** 2, '16^2': 16.0 ** 2}
    by_power = {name: curve(N, f0s, power=p) for name, p in powers.items()}

    measured_f0s = np.array([0.1, 0.5, 1, 2, 5, 10, 20, 30, 50, 70, 100, 120, 150, 200, 227.0])
    measured = {kind: measure(kind, measured_f0s, args.seeds)
                for kind in ('white noise', '1/f noise')}
    at_100 = int(np.flatnonzero(measured_f0s == 100)[0])
    predicted_at = curve(N, measured_f0s)

    def at(values: np.ndarray, f0: float) -> float:
        return float(np.interp(f0, f0s, values))

    summary = {
        'information_ratio_at_f0_100': at(thesis['information_ratio'], 100.0),
        'information_ratio_at_f0_120': at(thesis['information_ratio'], 120.0),
        'information_ratio_at_f0_227': at(thesis['information_ratio'], 227.0),
        'energy_ratio_at_f0_100': at(thesis['energy_ratio'], 100.0),
        'energy_ratio_at_f0_120': at(thesis['energy_ratio'], 120.0),
        'energy_ratio_parseval_at_f0_100': at(thesis['energy_ratio_parseval'], 100.0),
        'information_ratio_at_f0_1': at(thesis['information_ratio'], 1.0),
        'information_ratio_at_f0_10': at(thesis['information_ratio'], 10.0),
        'bits_per_pixel_original': float(thesis['bits_original'][0]),
        'bits_per_pixel_at_f0_100': at(thesis['bits_foveated'], 100.0),
        'f0_where_information_ratio_reaches': {
            str(level): crossing(f0s, thesis['information_ratio'], level)
            for level in (0.5, 0.9, 0.94, 0.95, 0.97, 0.98)},
        'information_ratio_gain_per_10px': {
            str(f): at(thesis['information_ratio'], f + 5) - at(thesis['information_ratio'], f - 5)
            for f in (20.0, 50.0, 100.0, 120.0, 150.0, 200.0)},
        'four_levels_information_ratio_at_f0_100': at(four_levels['information_ratio'], 100.0),
        'pyramid_sigma_1_information_ratio_at_f0_100': at(pyramid['information_ratio'], 100.0),
        'measured_white_noise_information_ratio_at_f0_100':
            measured['white noise']['information_ratio'][at_100],
        'measured_1_over_f_information_ratio_at_f0_100':
            measured['1/f noise']['information_ratio'][at_100],
        'max_abs_white_noise_minus_formula_information_ratio': float(np.max(np.abs(
            np.array(measured['white noise']['information_ratio'])
            - predicted_at['information_ratio']))),
        'max_abs_white_noise_minus_formula_energy_ratio': float(np.max(np.abs(
            np.array(measured['white noise']['energy_ratio']) - predicted_at['energy_ratio']))),
    }

    result = {
        'setting': {'N': N, 'sigma_1': SIGMA_1, 'levels': LEVELS, 'fixation': 'image centre',
                    'pixel_power': FULL_SCALE_POWER, 'f0_range': [0.1, 227.0],
                    'reference_for_ratios': 'unfoveated image analysed with the same equations '
                                            '(uncorrelated levels, every H_k = 1)',
                    'seeds_per_kind': args.seeds},
        'thesis': THESIS,
        'summary': summary,
        'curve': {'f0': f0s.tolist(), **{k: v.tolist() for k, v in thesis.items()}},
        'curve_four_levels': {'information_ratio': four_levels['information_ratio'].tolist(),
                              'energy_ratio': four_levels['energy_ratio'].tolist()},
        'curve_pyramid_sigma_1': {'sigma_1': PYRAMID_SIGMA_1,
                                  'information_ratio': pyramid['information_ratio'].tolist(),
                                  'energy_ratio': pyramid['energy_ratio'].tolist()},
        'by_image_size': {str(n): {'f0': np.geomspace(0.1, 2.0 * n, SIZE_POINTS).tolist(),
                                   'information_ratio': c['information_ratio'].tolist(),
                                   'energy_ratio': c['energy_ratio'].tolist(),
                                   'information_ratio_at_f0_over_N_0.44': float(np.interp(
                                       0.44 * n, np.geomspace(0.1, 2.0 * n, SIZE_POINTS),
                                       c['information_ratio']))}
                          for n, c in by_size.items()},
        'by_pixel_power': {name: {'information_ratio_at_f0_100': at(c['information_ratio'], 100.0),
                                  'bits_original': float(c['bits_original'][0])}
                           for name, c in by_power.items()},
        'measured': {'f0': measured_f0s.tolist(), **measured},
    }
    result['protocol'] = protocol_of(result, cpu_seconds())
    (args.out / 'fovea_information.json').write_text(json.dumps(rounded(result), indent=1) + '\n')
    plot(args.out / 'fovea_information.png', f0s, thesis, pyramid, by_size, by_power,
         measured_f0s, measured)
    print(f'wrote {args.out / "fovea_information.png"} and .json')
    print(json.dumps({k: summary[k] for k in (
        'information_ratio_at_f0_100', 'information_ratio_at_f0_120', 'energy_ratio_at_f0_100',
        'measured_white_noise_information_ratio_at_f0_100',
        'measured_1_over_f_information_ratio_at_f0_100')}))


def plot(path: Path, f0s: np.ndarray, thesis: dict, pyramid: dict, by_size: dict, by_power: dict,
         measured_f0s: np.ndarray, measured: dict) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(17, 10))
    ax = axes[0, 0]
    ax.plot(f0s, thesis['information_ratio'], 'b-', label='information ratio $Z_F/Z_I$ (Eq. 2.18)')
    ax.plot(f0s, thesis['energy_ratio'], 'r-', label='energy ratio $E_F/E_I$ (Eq. 2.15)')
    ax.plot(f0s, thesis['energy_ratio_parseval'], 'r:', label='energy ratio, $E_I = M^2$ (Eq. 2.5)')
    wn = measured['white noise']
    ax.errorbar(measured_f0s, wn['information_ratio'], wn['information_ratio_std'], fmt='bo',
                ms=4, label='measured, white noise')
    ax.errorbar(measured_f0s, wn['energy_ratio'], wn['energy_ratio_std'], fmt='ro', ms=4,
                label='measured, white noise')
    ax.axvline(100, color='grey', lw=0.8, ls='--')
    ax.axhline(0.94, color='grey', lw=0.8, ls='--')
    ax.annotate('thesis: 94 % at $f_0$ = 100', (100, 0.94), (110, 0.75),
                arrowprops={'arrowstyle': '->'})
    ax.set(xlabel='$f_0$ [px]', ylabel='ratio', xlim=(0, 227), ylim=(0, 1.02),
           title='Fig. 2.6: 227x227, $\\sigma_1$ = 1, K = 5, power $255^2$')
    ax.legend(fontsize=8, loc='lower right')

    ax = axes[0, 1]
    ax.semilogx(f0s, thesis['information_ratio'], 'b-', label='formula, $\\sigma_1$ = 1')
    ax.semilogx(f0s, pyramid['information_ratio'], 'c--',
                label=f'formula, $\\sigma_1$ = {PYRAMID_SIGMA_1:.2f} (real-time pyramid)')
    pn = measured['1/f noise']
    ax.errorbar(measured_f0s, pn['information_ratio'], pn['information_ratio_std'], fmt='gs',
                ms=4, label='measured, 1/f noise (std 40), information')
    ax.errorbar(measured_f0s, pn['energy_ratio'], pn['energy_ratio_std'], fmt='m^', ms=4,
                label='measured, 1/f noise, energy')
    ax.semilogx(f0s, thesis['energy_ratio'], 'r-', lw=0.8, label='formula energy, $\\sigma_1$ = 1')
    ax.set(xlabel='$f_0$ [px] (log)', ylabel='ratio', ylim=(0, 1.02),
           title='log scale; natural-image-like spectra keep more')
    ax.legend(fontsize=8, loc='lower right')

    ax = axes[0, 2]
    for n, c in by_size.items():
        ax.semilogx(np.geomspace(0.1, 2.0 * n, SIZE_POINTS), c['information_ratio'],
                    label=f'N = {n}')
    ax.set(xlabel='$f_0$ [px] (log)', ylabel='information ratio', ylim=(0, 1.02),
           title='image size N x N (formula)')
    ax.legend(fontsize=8)

    ax = axes[1, 0]
    for n, c in by_size.items():
        ax.semilogx(np.geomspace(0.1, 2.0 * n, SIZE_POINTS) / n, c['energy_ratio'],
                    label=f'N = {n}')
    ax.set(xlabel='$f_0$ / N (log)', ylabel='energy ratio', ylim=(0, 1.02),
           title='the ratios depend on $f_0$ / N only')
    ax.legend(fontsize=8)

    ax = axes[1, 1]
    for name, c in by_power.items():
        ax.plot(f0s, c['information_ratio'], label=f'pixel power {name}')
    ax.plot(f0s, thesis['energy_ratio'], 'k:', label='energy ratio (any power)')
    ax.set(xlabel='$f_0$ [px]', ylabel='ratio', xlim=(0, 227), ylim=(0, 1.02),
           title='the information ratio depends on the signal power')
    ax.legend(fontsize=8)

    ax = axes[1, 2]
    image = to_uint8(pink_noise(N, N, channels=3, seed=200))
    tiles = [image] + [Foveator(N, N, LEVELS, f0).foveate(image, (N // 2, N // 2))
                       for f0 in (10.0, 30.0, 100.0)]
    ax.imshow(np.concatenate([np.concatenate(tiles[:2], 1), np.concatenate(tiles[2:], 1)], 0))
    ax.set(title='1/f image: original, $f_0$ = 10 | 30, 100 (real-time pyramid)',
           xticks=[], yticks=[])
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == '__main__':
    main()
