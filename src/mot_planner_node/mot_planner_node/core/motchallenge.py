"""MOTChallenge sequence folders: ``img1/`` frames, ``gt/gt.txt``, optional ``seqinfo.ini``.

Ground-truth rows are ``frame, id, x, y, w, h[, conf[, class[, visibility]]]`` (MOT16, MOT17
and MOT20 have all nine; older sets put -1 in the unused columns). A file whose rows have ten
values is MOT15's layout, ``frame, id, x, y, w, h, conf, X, Y, Z`` (world coordinates, or -1):
it has no class or visibility, so its rows are read as class -1 (a target) with visibility 1.
Every row of a file must have the same number of values, 6 to 10; a class must be an integer
and a visibility -1 or in [0, 1] (anything else is some other layout, refused). What is evaluated
follows the MOTChallenge devkit: rows with conf 0 are ignored; with a class column, class 1
(pedestrian) and -1 (no class) are targets, classes 2, 7, 8, 12 (person on vehicle, static
person, distractor, reflection) are distractors (a hypothesis that matches one is not counted,
see :mod:`.metrics`), all other classes are ignored.

Every problem raises :class:`MotFolderError` naming the file (and line) and what is wrong.
"""

from __future__ import annotations

import configparser
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

TARGET_CLASSES = (1, -1)
MOT15_WIDTH = 10  # values per gt.txt row in MOT15 (2D MOT 2015): conf, then world x, y, z
DISTRACTOR_CLASSES = (2, 7, 8, 12)
IMAGE_EXTENSIONS = ('.jpg', '.jpeg', '.png', '.bmp')


class MotFolderError(ValueError):
    """A MOTChallenge folder or file that cannot be used."""


@dataclass
class GroundTruth:
    """Parsed gt.txt: one entry per row."""

    frames: IntArray
    ids: IntArray
    boxes: FloatArray
    conf: FloatArray
    classes: IntArray
    visibility: FloatArray

    @property
    def target(self) -> NDArray[np.bool_]:
        return (self.conf != 0) & np.isin(self.classes, TARGET_CLASSES)

    @property
    def distractor(self) -> NDArray[np.bool_]:
        return np.isin(self.classes, DISTRACTOR_CLASSES)

    def frame(self, f: int) -> tuple[IntArray, FloatArray, FloatArray]:
        """(target ids, target boxes (n, 4), distractor boxes (m, 4)) of frame f (1-based)."""
        at = self.frames == f
        t, d = at & self.target, at & self.distractor
        return self.ids[t], self.boxes[t], self.boxes[d]


@dataclass
class Sequence:
    """A sequence folder: frame files (index 0 is frame 1), image size, ground truth."""

    name: str
    path: Path
    frame_paths: list[Path]
    image_size: tuple[int, int] | None
    frame_rate: float | None
    gt: GroundTruth

    def __len__(self) -> int:
        return len(self.frame_paths)


def read_gt(path: Path, n_frames: int | None = None) -> GroundTruth:
    """Parse a MOTChallenge gt.txt (module docstring); frames beyond n_frames are an error."""
    if not path.is_file():
        raise MotFolderError(f'{path}: ground truth file not found')
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise MotFolderError(f'{path}: cannot read ({exc})') from None
    rows: list[list[float]] = []
    seen: set[tuple[int, int]] = set()
    lines = [ln.strip() for ln in text.splitlines()]
    split = [[f.strip() for f in ln.replace(' ', ',').split(',') if f.strip()] for ln in lines]
    width = next((len(f) for f in split if f), 0)
    mot15 = width == MOT15_WIDTH  # columns 8-10 are world coordinates, not class/visibility
    for lineno, line in enumerate(lines, 1):
        line = line.strip()
        if not line:
            continue
        fields = split[lineno - 1]
        where = f'{path} line {lineno}'
        if len(fields) < 6:
            raise MotFolderError(f'{where}: expected at least 6 comma-separated values '
                                 f'(frame, id, x, y, w, h), got {len(fields)}: {line!r}')
        if len(fields) > MOT15_WIDTH:
            raise MotFolderError(f'{where}: {len(fields)} values; MOTChallenge ground truth has '
                                 f'6 to 9 (MOT16/17/20: frame, id, x, y, w, h, conf, class, '
                                 f'visibility) or 10 (MOT15: ..., conf, X, Y, Z)')
        if len(fields) != width:
            raise MotFolderError(f'{where}: {len(fields)} values, but the first row has '
                                 f'{width}: one layout per file')
        try:
            vals = [float(v) for v in fields]
        except ValueError:
            raise MotFolderError(f'{where}: not a number in {line!r}') from None
        if not np.all(np.isfinite(vals)):
            raise MotFolderError(f'{where}: non-finite value in {line!r}')
        frame, tid = vals[0], vals[1]
        if frame != int(frame) or frame < 1:
            raise MotFolderError(f'{where}: frame must be an integer >= 1, got {fields[0]}')
        if tid != int(tid):
            raise MotFolderError(f'{where}: id must be an integer, got {fields[1]}')
        if n_frames is not None and frame > n_frames:
            raise MotFolderError(f'{where}: frame {int(frame)} is beyond the sequence\'s '
                                 f'{n_frames} frames')
        if vals[4] <= 0 or vals[5] <= 0:
            raise MotFolderError(f'{where}: box width and height must be > 0, got '
                                 f'{fields[4]} x {fields[5]}')
        key = (int(frame), int(tid))
        if key in seen:
            raise MotFolderError(f'{where}: id {int(tid)} appears twice in frame {int(frame)}')
        seen.add(key)
        if not mot15 and len(vals) >= 8 and vals[7] != int(vals[7]):
            raise MotFolderError(f'{where}: class must be an integer, got {fields[7]}')
        if not mot15 and len(vals) == 9 and vals[8] != -1 and not 0.0 <= vals[8] <= 1.0:
            raise MotFolderError(f'{where}: visibility must be in [0, 1] (or -1), got '
                                 f'{fields[8]}')
        if mot15:
            vals = vals[:7] + [-1.0, 1.0]
        vals += [1.0, -1.0, 1.0][len(vals) - 6:]            # conf, class, visibility defaults
        rows.append(vals[:9])
    a = np.array(rows, dtype=float).reshape(-1, 9)
    return GroundTruth(frames=a[:, 0].astype(np.int64), ids=a[:, 1].astype(np.int64),
                       boxes=a[:, 2:6].copy(), conf=a[:, 6].copy(),
                       classes=a[:, 7].astype(np.int64), visibility=a[:, 8].copy())


def _seqinfo(path: Path) -> dict[str, str]:
    parser = configparser.ConfigParser()
    try:
        parser.read_string(path.read_text())
    except (configparser.Error, OSError, UnicodeDecodeError) as exc:
        raise MotFolderError(f'{path}: not a valid ini file ({exc})') from None
    if 'Sequence' not in parser:
        raise MotFolderError(f'{path}: no [Sequence] section')
    return dict(parser['Sequence'])


def _int_field(info: dict[str, str], key: str, path: Path) -> int:
    if key.lower() not in info:
        raise MotFolderError(f'{path}: [Sequence] has no {key}')
    try:
        value = int(info[key.lower()])
    except ValueError:
        raise MotFolderError(
            f'{path}: {key} must be an integer, got {info[key.lower()]!r}') from None
    if value <= 0:
        raise MotFolderError(f'{path}: {key} must be > 0, got {value}')
    return value


def load_sequence(path: str | Path) -> Sequence:
    """Check and load a MOTChallenge sequence folder (module docstring)."""
    path = Path(path)
    if not path.is_dir():
        raise MotFolderError(f'{path}: not a folder')
    info_path = path / 'seqinfo.ini'
    name, frame_rate, size = path.name, None, None
    img_dir = path / 'img1'
    if info_path.is_file():
        info = _seqinfo(info_path)
        name = info.get('name', name)
        img_dir = path / info.get('imdir', 'img1')
        n = _int_field(info, 'seqLength', info_path)
        ext = info.get('imext', '.jpg')
        if 'imwidth' in info or 'imheight' in info:
            size = (_int_field(info, 'imWidth', info_path), _int_field(info, 'imHeight', info_path))
        if 'framerate' in info:
            try:
                frame_rate = float(info['framerate'])
            except ValueError:
                raise MotFolderError(f'{info_path}: frameRate must be a number, got '
                                     f'{info["framerate"]!r}') from None
        if not img_dir.is_dir():
            raise MotFolderError(f'{img_dir}: image folder not found')
        frames = [img_dir / f'{i:06d}{ext}' for i in range(1, n + 1)]
        missing = [p.name for p in frames if not p.is_file()]
        if missing:
            raise MotFolderError(f'{img_dir}: {len(missing)} of the {n} frames seqinfo.ini '
                                 f'announces are missing, first {missing[0]}')
    else:
        if not img_dir.is_dir():
            raise MotFolderError(f'{path}: no img1/ folder (and no seqinfo.ini naming another)')
        frames = sorted(p for p in img_dir.iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS)
        if not frames:
            raise MotFolderError(f'{img_dir}: no images ({", ".join(IMAGE_EXTENSIONS)})')
        for i, p in enumerate(frames, 1):
            if not p.stem.isdigit() or int(p.stem) != i:
                raise MotFolderError(f'{img_dir}: frames must be numbered 1, 2, ... (000001'
                                     f'{p.suffix}); file {i} is {p.name}')
    gt = read_gt(path / 'gt' / 'gt.txt', len(frames))
    return Sequence(name, path, frames, size, frame_rate, gt)


def find_sequences(path: str | Path) -> list[Path]:
    """The folder itself if it is a sequence (has img1/ or seqinfo.ini), else its
    sub-folders that are, sorted; MotFolderError if there are none."""
    path = Path(path)
    if not path.is_dir():
        raise MotFolderError(f'{path}: not a folder')

    def is_seq(p: Path) -> bool:
        return (p / 'img1').is_dir() or (p / 'seqinfo.ini').is_file()

    if is_seq(path):
        return [path]
    subs = sorted(p for p in path.iterdir() if p.is_dir() and is_seq(p))
    if not subs:
        raise MotFolderError(f'{path}: neither a MOTChallenge sequence (img1/, gt/gt.txt, '
                             'seqinfo.ini) nor a folder of them')
    return subs
