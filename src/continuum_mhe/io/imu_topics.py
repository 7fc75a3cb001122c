"""Several IMUs in one robot log: one ``sensor_msgs/msg/Imu`` topic per IMU, paired by
header stamp.

``--topic /imu1 --topic /imu2`` names the topics in the robot file's IMU order. Each
topic is read as in :mod:`continuum_mhe.io.robot_logs` (messages with a non-increasing
stamp skipped and counted); then samples are paired across topics by header stamp: a
sample of IMU 1 and one of IMU ``k`` are a pair when each is the other's nearest in time
(mutual nearest neighbours, so no sample is used twice) and their stamps differ by at
most the tolerance; a sample of IMU 1 left without a partner then takes the nearest
sample within the tolerance that no pair took, between its neighbours' partners (two
IMUs about half a period out of phase, whose nearest samples are each other's
neighbours'). Every sample of IMU 1 is a sample, at IMU 1's stamp; where IMU 1
is silent between two of its samples, or after its last one, for more than one and a
half of its median sample periods (an outage) while another topic goes on, or before its
first one while another topic has begun, that topic's samples there are samples too
(:func:`fill_outages`), thinned to at least three quarters of IMU 1's period apart, IMU
1's reading missing. ``t`` counts from the first sample (IMU 1's, or that of a topic
that began before it, which the line says), as a single topic's does. A sample without
a partner in a topic has that IMU's reading missing (a dropout of that IMU, as a
table's row with its fields empty). The default tolerance is half of IMU 1's median
sample period (a pair is then always closer than the next sample);
``--pair-tolerance`` sets it in seconds.
The dropouts and the samples of the topics left without a partner are counted per
topic and reported in one line, which says where IMU 1 began after another topic, and
where a topic's stamps lie far from IMU 1's and many of its samples found no partner
(IMUs sampling out of phase). A run in which many samples restarted the estimator
gets one warning that the topics may be out of order (:func:`warn_topic_order`), and
so do topics whose names number them in another order than the one given
(:func:`warn_numbers_out_of_order`). Topics whose header stamps stand
apart from one another against the log's own times (:func:`warn_clocks_apart`) get one
warning too: paired by stamp, their readings may be from different instants.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError
from continuum_mhe.io.robot_logs import (
    IMU_TYPES,
    ImuLog,
    log_topics,
    read_imu_log,
    topics_line,
)

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class PairedImus:
    """IMU samples of several topics, paired by header stamp on IMU 1's samples and
    those that fill IMU 1's outages.

    Attributes:
        logs: per topic (robot-file order), its samples at those of ``t``: a sample
            without a partner in a topic is NaN there (a dropout of that IMU; its
            ``numbers`` 0).
        t: (n,) s since ``t0_ns``: IMU 1's stamps, and other topics' stamps where IMU 1
            had an outage or had not started (:func:`fill_outages`).
        t0_ns: absolute time of the first sample, ns: IMU 1's first, or an earlier one
            of a topic that started before IMU 1.
        tolerance_s: largest stamp difference accepted in a pair, s.
        read: samples read per topic (after skipping non-increasing stamps).
        partners: per topic, the samples with a partner in it (IMU 1: its own).
        skipped: descriptions of skipped messages, prefixed by their topic.
        offsets_s: per topic, the median distance of its stamps from the nearest of
            IMU 1's, s (IMU 1's: 0).
        starts_s: per topic, its first stamp, s since ``t0_ns`` (negative for a sample
            before the first one, too close to it to be one of its own).
    """

    logs: tuple[ImuLog, ...]
    t: FloatArray
    t0_ns: int
    tolerance_s: float
    read: tuple[int, ...]
    partners: tuple[int, ...] = ()
    skipped: list[str] = field(default_factory=list)
    offsets_s: tuple[float, ...] = ()
    starts_s: tuple[float, ...] = ()

    @property
    def unpaired(self) -> tuple[int, ...]:
        """Samples of each topic left without a partner among the samples (unused)."""
        return tuple(r - p for r, p in zip(self.read, self.partners))

    @property
    def dropouts(self) -> tuple[int, ...]:
        """The samples without a partner in each topic (that IMU's dropouts; IMU 1's:
        the samples filling its outages)."""
        return tuple(len(self.t) - p for p in self.partners)

    def report(self) -> str:
        """One line: samples, tolerance, dropouts and unpaired samples per topic (IMU
        1's dropouts where it had outages)."""
        topics = ", ".join(log.topic for log in self.logs)
        left = ", ".join(f"{log.topic} {u}" for log, u in zip(self.logs, self.unpaired))
        missing = ", ".join(
            f"{log.topic} {d}" for k, (log, d) in enumerate(zip(self.logs, self.dropouts))
            if k > 0 or d > 0
        )  # fmt: skip
        clocks = sorted({log.clock for log in self.logs})
        return (
            f"paired {len(self.t)} samples of {len(self.logs)} topics ({topics}) by "
            f"{' and '.join(clocks)} within {_duration(self.tolerance_s)}; without a "
            f"partner (a dropout of that IMU): {missing}; unpaired: {left}"
            + self._late_start_clause()
            + self._phase_clause()
        )

    def _late_start_clause(self) -> str:
        """Where IMU 1 started after another topic, whose samples before IMU 1's first
        are estimated (IMU 1 missing there): a clause saying where ``t = 0`` is."""
        if not self.starts_s or self.starts_s[0] <= 0.0:
            return ""
        first = self.logs[1 + int(np.argmin(np.abs(self.starts_s[1:])))].topic  # at t = 0
        return (
            f"; {self.logs[0].topic} starts {_duration(self.starts_s[0])} after {first}: "
            f"t = 0 at {first}'s first stamp, {self.logs[0].topic}'s reading missing before "
            "its first"
        )

    def _phase_clause(self) -> str:
        """Where more than :data:`UNPAIRED_SHARE` of a topic's samples found no partner,
        as many of IMU 1's samples have none in it (not a faster topic, whose extra
        samples are left over beside a partner for every sample), and its stamps lie a
        median of more than half the tolerance from IMU 1's (two IMUs sampling out of
        phase, not a topic's own gaps): a clause saying so."""
        n = len(self.t)
        said = [
            f"{log.topic}'s stamps lie a median {_duration(offset)} from {self.logs[0].topic}'s"
            for log, offset, unpaired, read, dropouts in zip(
                self.logs[1:],
                self.offsets_s[1:],
                self.unpaired[1:],
                self.read[1:],
                self.dropouts[1:],
            )
            if unpaired > UNPAIRED_SHARE * read
            and dropouts > UNPAIRED_SHARE * n
            and offset > 0.5 * self.tolerance_s
        ]
        if not said:
            return ""
        return (
            f"; {', '.join(said)}: the IMUs sample out of phase, and a larger "
            "--pair-tolerance pairs more of their readings (each taken at IMU 1's time, "
            "up to that far from its own)"
        )


#: A topic with more than this share of its samples left without a partner, whose stamps
#: lie far from IMU 1's, is said to sample out of phase (:meth:`PairedImus.report`).
UNPAIRED_SHARE = 0.1


def _duration(seconds: float) -> str:
    """``12.5 ms`` below a second, ``2 s`` from there."""
    return f"{seconds * 1e3:.3g} ms" if seconds < 1.0 else f"{seconds:.3g} s"


def _stamps_ns(log: ImuLog) -> IntArray:
    return log.t0_ns + np.round(log.t * 1e9).astype(np.int64)


def _nearest(src: IntArray, dst: IntArray) -> IntArray:
    """Index in sorted ``dst`` of the nearest value to each of ``src`` (ties: later)."""
    hi = np.clip(np.searchsorted(dst, src), 0, len(dst) - 1)
    lo = np.clip(hi - 1, 0, len(dst) - 1)
    return np.where(np.abs(dst[lo] - src) < np.abs(dst[hi] - src), lo, hi)


def pair_stamps(stamps: Sequence[IntArray], tolerance_ns: int) -> list[IntArray]:
    """Per topic of ``stamps`` (increasing, ns), for each sample of ``stamps[0]`` the
    index of its partner in that topic (mutual nearest, within the tolerance), or -1
    where it has none; the first array is ``stamps[0]``'s own indices."""
    ref = stamps[0]
    out = [np.arange(len(ref), dtype=np.int64)]
    for other in stamps[1:]:
        j = _nearest(ref, other)
        back = _nearest(other, ref)
        paired = (back[j] == np.arange(len(ref))) & (np.abs(other[j] - ref) <= tolerance_ns)
        idx = np.where(paired, j, -1).astype(np.int64)
        _pair_leftovers(ref, other, idx, tolerance_ns)
        out.append(idx)
    return out


def _pair_leftovers(ref: IntArray, other: IntArray, idx: IntArray, tolerance_ns: int) -> None:
    """Pair, in place, each sample of ``ref`` left without a partner with the nearest
    sample of ``other`` within the tolerance that no sample took, between the partners
    of its paired neighbours (the order kept): two sensors half a period apart leave
    two candidates for one partner at every jitter, which mutual nearest pairing loses."""
    left = np.flatnonzero(idx < 0)
    if not len(left) or not len(other):
        return
    # the pairs are in order: between the last partner before a sample and the next
    # after it, every sample of ``other`` is free but those given to leftovers before
    before = np.maximum.accumulate(idx)  # the last partner up to each sample (-1: none)
    after = np.minimum.accumulate(np.where(idx >= 0, idx, len(other))[::-1])[::-1]
    lows = np.searchsorted(other, ref[left] - tolerance_ns)
    highs = np.searchsorted(other, ref[left] + tolerance_ns, side="right")
    last = -1  # the partner given to the leftover before
    for i, low, high in zip(left.tolist(), lows.tolist(), highs.tolist()):
        nxt = int(after[i + 1]) if i + 1 < len(ref) else len(other)
        cand = range(max(int(before[i]) + 1, last + 1, low), min(nxt, high))
        if len(cand):
            k = min(cand, key=lambda k: abs(int(other[k]) - int(ref[i])))
            idx[i] = k
            last = k


#: The samples silent for more than this many of IMU 1's median sample periods, between
#: two of IMU 1's samples or after its last one while another topic goes on, are an
#: outage, which the other topics' samples fill (:func:`fill_outages`).
OUTAGE_PERIODS = 1.5
#: Samples that fill an outage are at least this many of IMU 1's periods apart, and
#: from the samples around them (a faster topic's samples are thinned to about IMU 1's
#: rate).
FILL_SPACING_PERIODS = 0.75


def fill_outages(stamps: Sequence[IntArray], period_ns: float, tolerance_ns: int) -> IntArray:
    """The samples' stamps (ns, increasing): IMU 1's (``stamps[0]``), and where those
    taken so far are silent for more than :data:`OUTAGE_PERIODS` of ``period_ns``
    between two of IMU 1's samples, or after the last one taken while the next topic
    goes on for longer (IMU 1 stopped first), or before the first one taken while the
    next topic has samples there (IMU 1 started later), the stamps of the next topic
    there, topic by topic in order (IMU 3's only where IMU 2 is silent too): each
    farther than ``tolerance_ns`` and at least :data:`FILL_SPACING_PERIODS` periods
    from every stamp taken before. A stamp taken that would take a sample of another
    topic away from the IMU 1 sample it pairs with (mutual nearest,
    :func:`pair_stamps`) is left out. The estimates' time starts at the first stamp
    returned."""
    ref = stamps[0]
    outage = OUTAGE_PERIODS * period_ns
    apart = max(float(tolerance_ns), FILL_SPACING_PERIODS * period_ns)
    last_other = max((int(o[-1]) for o in stamps[1:] if len(o)), default=-1)
    first_other = min((int(o[0]) for o in stamps[1:] if len(o)), default=None)
    if len(ref) < 2:
        return ref
    head = first_other is not None and int(ref[0]) - first_other >= apart
    if not (head or (np.diff(ref) > outage).any() or last_other - int(ref[-1]) > outage):
        return ref
    timeline = ref
    for other in stamps[1:]:
        gaps = [int(g) for g in np.flatnonzero(np.diff(timeline) > outage)]
        end = int(timeline[-1])
        if len(other) and int(other[-1]) - end > outage:  # the tail: an open gap
            gaps.append(len(timeline) - 1)
        taken: list[int] = []
        start = int(timeline[0])  # the head: before the first stamp taken, open
        for s in other[other < start]:
            if start - s >= apart and (not taken or s - taken[-1] >= apart):
                taken.append(int(s))
        for g in gaps:
            last = int(timeline[g])  # the gap's start; its end is timeline[g + 1]
            closed = g + 1 < len(timeline)
            stop = int(timeline[g + 1]) if closed else int(other[-1]) + 1
            for s in other[(other > timeline[g]) & (other < stop)]:
                if s - last >= apart and (not closed or stop - s >= apart):
                    taken.append(int(s))
                    last = int(s)
        if taken:
            timeline = np.sort(np.concatenate([timeline, np.asarray(taken, dtype=np.int64)]))
    # no fill may take a partner from one of IMU 1's samples: where one would, the
    # filled stamp nearest that partner is left out, until none does
    if len(timeline) == len(ref):
        return ref
    before = pair_stamps(stamps, tolerance_ns)
    while len(timeline) > len(ref):
        at = np.searchsorted(timeline, ref)  # IMU 1's samples among them
        after = pair_stamps([timeline, *stamps[1:]], tolerance_ns)
        lost = [
            (k, int(b[i]))
            for k, (b, a) in enumerate(zip(before[1:], after[1:]), start=1)
            for i in np.flatnonzero((b >= 0) & (a[at] != b))
        ]
        if not lost:
            break
        filled = np.setdiff1d(timeline, ref)
        drop = {int(filled[_nearest(np.array([stamps[k][j]]), filled)[0]]) for k, j in lost}
        timeline = timeline[~np.isin(timeline, list(drop))]
    return timeline


def _subset(log: ImuLog, idx: IntArray, t: FloatArray, t0_ns: int) -> ImuLog:
    """``log`` at the samples ``idx`` (-1: none there, NaN values and message 0)."""
    has = idx >= 0
    take = np.where(has, idx, 0)

    def rows(a: FloatArray) -> FloatArray:
        out = a[take].copy()
        out[~has] = np.nan
        return out

    return ImuLog(
        topic=log.topic, t=t, t0_ns=t0_ns, acc=rows(log.acc),
        gyr=None if log.gyr is None else rows(log.gyr), orientation=rows(log.orientation),
        skipped=log.skipped, clock=log.clock, cut=log.cut,
        stamp_offset_s=log.stamp_offset_s, frames=log.frames,
        numbers=None if log.numbers is None else np.where(has, log.numbers[take], 0),
        stale_stamps=log.stale_stamps, reordered=log.reordered,
    )  # fmt: skip


def read_imu_topics(
    path: str | Path,
    topics: Sequence[str],
    n_imus: int,
    tolerance_s: float | None = None,
    skip_bad: bool = False,
) -> PairedImus:
    """Read one Imu topic per IMU (``topics`` in the robot file's IMU order) from a bag
    or MCAP file and pair their samples by header stamp (see the module doc);
    ``skip_bad``: an MCAP file cut short is read up to the cut
    (:func:`~continuum_mhe.io.robot_logs.read_imu_log`)."""
    p = Path(path)
    if len(topics) != n_imus:
        given = f"{len(topics)} --topic" if topics else "no --topic"
        imus = f"{n_imus} IMU{'s' if n_imus > 1 else ''}"
        held = log_topics(p)
        if not any(typ in IMU_TYPES for typ in held.values()):  # no --topic can help
            raise InputError(f"{p}: {topics_line(held)} (a robot with {imus} needs one per IMU)")
        imu_topics = sum(typ in IMU_TYPES for typ in held.values())
        fewer = (
            f" (the log has {imu_topics} Imu topic(s) for {imus}: one topic carrying several "
            "IMUs' messages, told apart by header.frame_id, is not read; record one topic "
            "per IMU)"
            if imu_topics < n_imus
            else ""
        )
        raise InputError(
            f"{p}: {given} for a robot with {imus}: pass one --topic per IMU, in the robot "
            f"file's order; {topics_line(held)}{fewer}"
        )
    if len(set(topics)) != len(topics):
        raise InputError(f"{p}: a --topic is given twice ({', '.join(topics)})")
    if tolerance_s is not None and not (np.isfinite(tolerance_s) and tolerance_s > 0):
        raise InputError(f"--pair-tolerance must be positive seconds, got {tolerance_s}")
    logs = [read_imu_log(p, topic, skip_bad) for topic in topics]
    stamps = [_stamps_ns(log) for log in logs]
    # half of IMU 1's median sample period: the default tolerance, and the clock check's
    # measure of a period (a --pair-tolerance does not widen what that check allows)
    half_period_s = 0.5 * float(np.median(np.diff(stamps[0]))) / 1e9 if len(stamps[0]) > 1 else 0.0
    if tolerance_s is None:
        if len(stamps[0]) < 2:
            raise InputError(f"{p}: topic {topics[0]} has one sample: pass --pair-tolerance")
        tolerance_s = half_period_s
    tolerance_ns = int(round(tolerance_s * 1e9))
    idx = pair_stamps(stamps, tolerance_ns)
    for topic, i in zip(topics[1:], idx[1:]):
        if not (i >= 0).any():
            raise InputError(
                f"{p}: no sample of {topic} pairs with one of {topics[0]} within "
                f"{_duration(tolerance_s)} (--pair-tolerance)"
            )
    # IMU 1's outages filled by the other topics: every topic paired on the samples
    timeline = fill_outages(stamps, 2.0 * half_period_s * 1e9, tolerance_ns)
    if len(timeline) > len(stamps[0]):
        idx = pair_stamps([timeline, *stamps], tolerance_ns)[1:]
    # the topics are read and paired: what they may get wrong is said now, after the
    # refusals above (a refusal is its one line alone)
    warn_numbers_out_of_order(str(p), topics)
    warn_clocks_apart(str(p), logs, half_period_s)
    # the first sample's stamp: IMU 1's, or another topic's that started before it (its
    # samples there estimated, IMU 1 missing), so that t counts from the log's first
    # IMU sample; a topic that starts later does not move it
    t0 = int(timeline[0])
    t = (timeline - t0) / 1e9
    return PairedImus(
        logs=tuple(_subset(log, i, t, t0) for log, i in zip(logs, idx)),
        t=t,
        t0_ns=t0,
        tolerance_s=tolerance_s,
        read=tuple(len(s) for s in stamps),
        partners=tuple(int((i >= 0).sum()) for i in idx),
        skipped=[f"{log.topic}: {s}" for log in logs for s in log.skipped],
        offsets_s=tuple(
            float(np.median(np.abs(s - stamps[0][_nearest(s, stamps[0])]))) / 1e9 for s in stamps
        ),
        starts_s=tuple((int(s[0]) - t0) / 1e9 for s in stamps),
    )


#: A run from several Imu topics in which more than this share of the samples restarted
#: the estimator (readings inconsistent with its estimate, a diverged estimate) warns that
#: the topics may not be in the robot file's IMU order. Two sections, raw IMUs
#: (``--imu-model direct``, EKF, the uncalibrated ``two-section`` file): the shipped rod
#: recordings in the right order restart on 0 to 2.2 % of their samples, with IMU 1 and
#: IMU 2 swapped on 22 % (G = 5E rod) and 33 % (tendon), but 0 % on the planar S, whose
#: swapped readings fit another shape, as tilt input's do on every recording (under 1 %:
#: not caught); the rod that twists by 120 deg, which the model cannot explain, restarts
#: on 33 % and 34 % (warned in either order). A robot file with calibrated gyro biases
#: lets the readings choose the IMUs' twist, which a swap's readings favour and which
#: then explains them: 0 to 3 % restart (the twist clause of the summary names the order).
ORDER_RESTART_SHARE = 0.05


class TopicOrderWarning(UserWarning):
    """Many restarts in a run from several Imu topics: they may be out of order."""


def topic_numbers(topics: Sequence[str]) -> list[int] | None:
    """The number that tells each topic apart (``/imu2/data`` -> 2): where the names are
    the same but for their numbers, the numbers at the one position where they differ;
    None where no such one number does (``/vn100/imu``, ``/um7/imu``: two makes)."""
    if len({re.sub(r"\d+", "#", t) for t in topics}) != 1:
        return None
    found = [[int(n) for n in re.findall(r"\d+", t)] for t in topics]
    if not found[0]:
        return None
    differing = [i for i in range(len(found[0])) if len({f[i] for f in found}) > 1]
    if len(differing) != 1:
        return None
    return [f[differing[0]] for f in found]


def warn_numbers_out_of_order(name: str, topics: Sequence[str]) -> None:
    """One :class:`TopicOrderWarning` when the topics' names number them otherwise than
    in the order given (``--topic /imu2/data --topic /imu1/data``): the order given is
    the robot file's IMU order, IMU 1 nearest the base, and a swap that fits another
    shape is not seen in the readings."""
    numbers = topic_numbers(topics)
    if numbers is None or numbers == sorted(numbers):
        return
    first = topics[numbers.index(min(numbers))]
    warnings.warn(
        f"{name}: the topics are given as {', '.join(topics)}, against the numbers in their "
        "names: the first --topic is IMU 1 of the robot file (nearest the base), the next "
        f"IMU 2, ...; if {first} is the IMU nearest the base, give it first (IMUs in the "
        "wrong order can give estimates far off that fit the readings, or a calibration "
        "written to the wrong IMU)",
        TopicOrderWarning,
        stacklevel=3,
    )


def warn_topic_order(name: str, topics: Sequence[str], samples: int, restarts: int) -> None:
    """One :class:`TopicOrderWarning` when more than :data:`ORDER_RESTART_SHARE` of
    ``samples`` restarted the estimator (``restarts``, gaps not counted) in a run from
    several ``topics``."""
    if len(topics) < 2 or restarts <= ORDER_RESTART_SHARE * samples:
        return
    warnings.warn(
        f"{name}: {restarts} of {samples} samples ({100 * restarts / samples:.0f} %) restarted "
        "the estimator (readings inconsistent with its estimate): the readings do not fit "
        f"the robot; check that the --topic order ({', '.join(topics)}) is the robot file's "
        "IMU order (IMU 1 nearest the base)",
        TopicOrderWarning,
        stacklevel=2,
    )


#: Topics whose header stamps' offsets from the log's times (medians) differ by more
#: than this (s), or by more than IMU 1's sample period, get one
#: :class:`TopicClockWarning`: a delivery delay that differs between topics by this much
#: is unusual, sensors on clocks of their own are not.
CLOCKS_APART_S = 0.1


class TopicClockWarning(UserWarning):
    """The topics' header stamps are on clocks that stand apart: pairs by stamp may join
    readings taken at different instants."""


def warn_clocks_apart(name: str, logs: Sequence[ImuLog], half_period_s: float) -> None:
    """One :class:`TopicClockWarning` where a topic's header stamps stand apart from IMU
    1's against the log's own times (:attr:`ImuLog.stamp_offset_s`, a median) by more
    than :data:`CLOCKS_APART_S` or IMU 1's sample period (twice ``half_period_s``): the
    log's times are one clock for every topic, so such a difference is the sensors'
    clocks (or a delivery delay of one topic), and pairing by stamp joins readings that
    far apart in time; and where some topics are timed by their header stamps and others
    by the log's times (every stamp zero, or stamps that do not advance), which pairs a
    sensor's instant with a message's arrival, its delivery delay unseen."""
    clocks = {log.clock for log in logs}
    if len(clocks) > 1:
        by_log = [log for log in logs if log.clock != "header stamps"]
        zero = [log.topic for log in by_log if not log.stale_stamps]
        stale = [log.topic for log in by_log if log.stale_stamps]
        what = []
        if zero:
            what.append(
                f"{', '.join(zero)} {'has' if len(zero) == 1 else 'have'} no header stamps "
                "(every one zero)"
            )
        if stale:
            what.append(
                f"{', '.join(stale)} {'has' if len(stale) == 1 else 'have'} header stamps "
                "that do not advance (a driver that does not set header.stamp?)"
            )
        warnings.warn(
            f"{name}: {' and '.join(what)} and {'is' if len(by_log) == 1 else 'are'} timed "
            "by the log's own times, the other topics by "
            "their stamps: each pair joins a sensor's instant with a message's arrival, "
            "later by its delivery delay, which the log cannot show; stamp every IMU on "
            "one clock (readings paired across a motion give estimates that can be far "
            "off)",
            TopicClockWarning,
            stacklevel=3,
        )
        return
    ref = logs[0]
    if ref.clock != "header stamps":
        return
    limit = max(CLOCKS_APART_S, 2.0 * half_period_s)
    apart = [
        (log, log.stamp_offset_s - ref.stamp_offset_s)
        for log in logs[1:]
        if log.clock == "header stamps" and abs(log.stamp_offset_s - ref.stamp_offset_s) > limit
    ]
    if not apart:
        return
    said = "; ".join(
        f"{log.topic}'s header stamps are {_duration(abs(d))} "
        f"{'ahead of' if d > 0 else 'behind'} {ref.topic}'s"
        for log, d in apart
    )
    warnings.warn(
        f"{name}: {said}, against the log's own times (medians): sensors on clocks of "
        "their own? The samples are paired by their stamps, so each "
        "pair may join readings taken that far apart; stamp every IMU on one clock "
        "(readings paired across a motion give estimates that can be far off)",
        TopicClockWarning,
        stacklevel=3,
    )
