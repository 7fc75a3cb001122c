"""``live``'s tension glitch test against a tensions file's (docs/tendon.md, the
tensions file and live with tensions), on the shipped ``force-29``'s tensions with a load
cell's noise added: normal, ``--noise`` N (1 mN) on each of its six tendons, one draw per
seed, slack readings below zero taken as 0 as a file's and ``live``'s are.

* the samples ``live`` holds as candidate glitches until they are judged (four samples'
  wait instead of two: :class:`~continuum_mhe.io.tension_glitches.StreamGlitches`), per
  seed;
* glitches of each ``--sizes`` (N, added to one tension at one row): per seed, ten copies
  of the tensions with four glitches each (rows 40 + o, 120 + o, 200 + o and 280 + o for
  o = 0, 8, ..., 72, the tendons in turn), judged by a file's test
  (:func:`~continuum_mhe.io.tension_glitches.tension_glitches`, its noise estimated from
  the rows) and by ``live``'s (``stream_glitches``, as a recording's own tension columns
  are judged): the share each misses, and the share both miss.

::

    python tools/live_glitch_study.py                   # seeds 0 to 9, 0.02 and 0.05 N
    python tools/live_glitch_study.py --seeds 3 --sizes 0.02
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe.io.slack_readings import take_slack_readings
from continuum_mhe.io.tension_derivatives import tension_noise_std
from continuum_mhe.io.tension_glitches import StreamGlitches, stream_glitches, tension_glitches
from continuum_mhe.io.tensions import NOISE_CHECK_ROWS

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def noisy(values: np.ndarray, noise: float, seed: int) -> np.ndarray:
    """``values`` with normal noise of ``noise`` N, slack readings below zero taken as 0."""
    drawn = values + np.random.default_rng(seed).normal(0.0, noise, values.shape)
    return np.asarray(take_slack_readings(drawn).values, dtype=float)


def candidates(t: np.ndarray, values: np.ndarray) -> int:
    """The samples ``live``'s glitch test holds as candidates when they come."""
    watch = StreamGlitches(NOISE_CHECK_ROWS)
    held = 0
    for tk, vk in zip(t, values):
        watch.push(float(tk), vk)
        held += watch.waiting(watch.seen - 1, watch.seen - 1)
    return held


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=10, help="noise draws 0 to SEEDS - 1 (10)")
    p.add_argument("--sizes", type=float, nargs="+", default=[0.02, 0.05], help="N")
    p.add_argument("--noise", type=float, default=1e-3, help="N (1 mN)")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    table = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)
    t, given = table[:, 0], table[:, 1:]
    print(f"force-29, {args.noise * 1e3:g} mN of noise on each tendon; {len(t)} samples")
    for seed in range(args.seeds):
        print(f"  seed {seed}: {candidates(t, noisy(given, args.noise, seed))} candidates")
    for size in args.sizes:
        glitches = file_missed = live_missed = both_missed = 0
        for seed in range(args.seeds):
            base = noisy(given, args.noise, seed)
            for offset in range(0, 80, 8):
                values = base.copy()
                placed = [(40 + offset + 80 * q, (offset // 8 + q) % 6) for q in range(4)]
                for row, tendon in placed:
                    values[row, tendon] += size
                by_file = tension_glitches(t, values, tension_noise_std(values, t)).mask
                by_live = stream_glitches(t, values, NOISE_CHECK_ROWS).mask
                for row, tendon in placed:
                    glitches += 1
                    file_missed += not by_file[row, tendon]
                    live_missed += not by_live[row, tendon]
                    both_missed += not (by_file[row, tendon] or by_live[row, tendon])
        print(
            f"  {size:g} N glitches: {glitches}; missed by the file's test {file_missed} "
            f"({100 * file_missed / glitches:.1f} %), by live's {live_missed} "
            f"({100 * live_missed / glitches:.1f} %), by both {both_missed}",
            flush=True,
        )


if __name__ == "__main__":
    main()
