"""The `protocol` object that every results JSON of experiments/ carries (issue 16).

One place for its shape, so a reader (and scripts/results_table.py) finds the same five keys in
every file:

- data: what the experiment ran on (scene, sequences, photos, synthetic generator);
- repetitions: how many independent runs / scenes / trials stand behind each reported number
  (an int, or {condition: int} where conditions differ);
- thesis_repetitions: the same count in the thesis (None where the thesis gives none or the
  experiment has no thesis counterpart);
- models: the learned models or detectors used ('none' for pure geometry);
- differs_from_thesis: the list of ways the protocol differs from the thesis's.

Optional: cpu_s (process CPU seconds of the run, worker processes included), and anything else
the script wants to state (free keys after the five).

`--quick` runs never overwrite a full result: they write `<stem>_quick.*` (`result_stem`).
"""

from __future__ import annotations

import resource
import time
from typing import Any

KEYS = ('data', 'repetitions', 'thesis_repetitions', 'models', 'differs_from_thesis')


def protocol(*, data: str, repetitions: int | dict[str, int] | None,
             thesis_repetitions: int | dict[str, int] | None, models: str,
             differs_from_thesis: list[str], cpu_s: float | None = None,
             **extra: Any) -> dict[str, Any]:
    """The protocol object, keys in the documented order; cpu_s rounded to 0.1 s."""
    out: dict[str, Any] = {'data': data, 'repetitions': repetitions,
                           'thesis_repetitions': thesis_repetitions, 'models': models,
                           'differs_from_thesis': list(differs_from_thesis)}
    if cpu_s is not None:
        out['cpu_s'] = round(float(cpu_s), 1)
    out.update(extra)
    return out


def cpu_seconds() -> float:
    """CPU time of this process plus its waited-for children (multiprocessing workers)."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + kids.ru_utime + kids.ru_stime


def result_stem(name: str, quick: bool) -> str:
    """The file stem of a result: `--quick` runs get `_quick` so they never overwrite the full
    result."""
    return f'{name}_quick' if quick else name
