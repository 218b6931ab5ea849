"""Falls: a tracked person who goes from standing to lying quickly and stays down.

Pure logic, like :mod:`service.outputs.zones`: :class:`FallDetector` is fed one snapshot at a
time (``update(t, people)``, the people with the ``posture`` the tracker estimates,
:mod:`service.tracking.posture`) and returns the ``fall`` and ``fall_cleared`` events that
snapshot confirmed. Time is the snapshot's capture time ``t``, never the wall clock, so a
recording replays the same events and tests drive it with any clock they like.

Rules (per track id; :class:`FallRules`, settings ``falls.*``)
---------------------------------------------------------------
1. **A quick drop**: the first ``lying`` posture no later than ``max_drop_s`` (2 s) after the
   track last read ``standing``, once it has been upright for at least ``min_standing_s`` (1.5 s)
   from its first standing read (sitting in between does not break it: someone who gets up
   from a chair and falls is a fall), starts a candidate. Only what a camera sees now counts:
   a coasting track (the snapshot's ``cameras`` empty) carries its last posture, and through
   the serving chain such carried ``standing`` reads of tracks that had lost their person,
   then fed a lying association, raised false falls; so did tracks born a moment before,
   standing for one snapshot, and a ghost pair of two cameras' boxes read standing for 1.2 s
   where nobody stood, then read lying by one camera (``bench/results/falls.md``: 1 s until
   2026-12-07; 1.5 s lost none of the simulated falls, 2 s one of 240). Lying down on
   purpose goes through sitting for longer than that (onto a sofa, a bed, the floor), and a
   track that was never seen standing (someone already lying when the daemon starts) is never
   a candidate. No camera seeing the track for longer than ``upright_unseen_s`` (2 s) ends its
   upright streak: the tracker holds a still person's track at their place for seconds after
   they leave, and a false box that then feeds it standing is not a person who has stood
   there all along. In held-out daily life of the lounge such a held track, fed a false box
   read standing, then a sitter's box re-read lying beside it, raised a false fall 0.8 s after
   it was seen again (``bench/results/falls.md``; 2-5 s lost none of the simulated falls, 1 s
   one of 120 fresh ones). The price: someone no camera saw for 2 s who falls within 1.5 s of
   being seen again is no candidate. The drop must also come within ``max_drop_s`` of a *sure*
   standing read (posture confidence at least ``standing_confidence``, 0.75): a sitter's track
   left at the sofa when its person walked off read standing only unsurely (0.42-0.72), was
   held there, and a false box read lying at the sofa made it a fall (the lounge's daily life
   through the chain, ``bench/results/falls.md``). The price: someone who falls while getting
   up, before their standing reads sure, is no candidate (the simulated falls are from
   standing: none lost).
   **1b. A fall the tracker handed to a new track** (``handover_m``, 1.5 m; 0: off): a person
   falling is what a tracker loses most easily (the body's boxes change shape and place within
   a second, a lone camera's view of it is read seated metres away), and the body on the floor
   then often becomes a new track, born lying, which rule 1 never lets fall. So a track never
   seen standing starts a candidate at its first lying read when another track saw the drop (a
   candidate of rule 1; its last standing read below ``standing_confidence``: lost while going
   down, its evidence already mixed; or no camera seeing it since its last standing read, sure
   or not: lost as the person went down), last stood within ``max_drop_s`` and within
   ``handover_m`` of the new track, and has not read standing or sitting since the new track
   appeared; the older track then gives its candidate up (one fall, one event) until it reads
   standing again. In two falls of the fresh seed sets a track born a moment before took the
   body, read lying by two cameras, after the faller's track was last seen standing for sure,
   and no event came; such a donor counts since 2026-12-07 evening, with no false fall more in
   144 person-hours of daily life nor in 280 fall scenes (``bench/results/falls.md``). In a
   held-out fall of the simulated lounge through the chain the older track
   was dragged 1.5 m away as the new one took the body (``bench/results/falls.md``). Only such a
   track donates: when any recently standing track could, tracks that had lost their person
   without a lying read (one a sitter's track at a scene's start) raised fall events matching
   no fall. Nor does a donor still on the body: one seen lying within ``ON_THE_BODY_S`` and
   nearer where it stood than the new track is keeps its candidate (the new track is a second
   track of the body; taking the fall over, it fired past the 3 s in one of the 96 falls).
   The candidate is dropped when two cameras then see the donor standing or sitting: its
   person is up, and the lying track was a ghost beside them. In the lounge's daily life through
   the chain a person sat down (their standing reads unsure on the way), a pair of two cameras'
   boxes read lying a metre away became a new track, and its fall fired while both cameras read
   the sitter seated (``bench/results/falls.md``). One camera's seated read is no such evidence:
   a body on the floor seen lengthwise reads seated.
   **1c. A candidate whose track is lost** (the tracker gave the body to another track, often
   one held nearby from before, which rule 1b never lets take over: it was not born lying)
   goes to the nearest track within ``handover_m`` that reads lying in a snapshot no camera
   sees the candidate's track in, within ``max_drop_s`` of the last one that did; a fall still
   active on that track (its person got up, and the track was held where they lay) is cleared
   first. Lost is absent from the snapshot, or coasting (served, no camera) without a lying
   read for ``ON_THE_BODY_S``: a track coasting a moment is still on the body. In one of the 96
   falls the faller's track, a candidate for 1.5 s, was lost and the track held at an earlier
   fall's place took the body, read lying by both cameras, and no event came; in another the
   faller's track coasted for a second while a track born 0.7 m away took the body, and the
   fall came 4.7 s late, once the coasting track was dropped. Taken at the first snapshot
   without it, a candidate coasting for 0.3 s went to a track held at an earlier fall's place
   1.1 m off, and that fall came 4.8 s late. Only a track within ``reach_m`` of where the
   person last stood takes it: one farther away can never fire (rule 2), and took the fall
   away from the faller's own track. In the lounge a pair of two cameras' boxes 1.15 m off,
   read lying, took the candidate of a faller's track coasting for 0.7 s; the faller's track
   then read lying on the body again and no event came (``bench/results/falls.md``). A track
   that gave its candidate away takes it back the same way: in another fall the faller's
   track, held 0.6 m off the body, lost it to a second track on the body, which then coasted
   while the faller's track came back to the body and read lying for sure, and no event came.
2. **Down for sure**: the candidate becomes a ``fall`` on the first snapshot that reads lying
   with a posture confidence of at least ``min_confidence`` (0.7), at most ``reach_m`` (1 m)
   from where the person last stood, once the track has read lying
   for ``lying_s`` (1.3 s) in all since the candidate began. A body on the floor seen
   lengthwise by one camera reads seated between its lying reads, so its share of lying
   evidence climbs slowly: at 0.7 two more of 240 fresh falls came within 3 s than at 0.75,
   with no more false falls in 114 person-hours of daily life; 0.65 added none of the fresh
   falls, and a sit-down into the armchair read lying and seated by turns reaches a 0.654 share
   (``bench/results/falls.md``). A snapshot no camera sees the track in (the detector often
   misses a body just down) also counts as that sure read within
   ``coast_s`` (1 s) of one, once two cameras have read the body lying for sure since the
   candidate began: in two of 120 fresh falls the faller's track read lying for sure, then
   coasted unseen through ``lying_s``, and the fall came 5 s late or never. One camera's sure
   reads, carried so, raised two false falls in the ten seed sets' daily life (a crouch seen
   lengthwise, a track held where its person had left). The reach: the body's centre lies
   within about half a body's length of the feet it fell from, and the tracks of the 39 falls
   reported in the simulated lounge were 0.01-0.65 m from that place, while a sitter's track
   that a lone seated view had dragged 1.3 m away read lying there (a false fall of the daily
   life through the chain, ``bench/results/falls.md``). A candidate whose track no camera
   has seen lying for ``lying_gap_s`` (5 s) is dropped. Without that bound a track that read
   lying once and then went unseen (held at its still place, its posture carried) for seconds
   fired when a mispaired lying box 0.9 m away fed it (the lounge's daily life through
   the chain, ``bench/results/falls.md``). Nor does a snapshot that one camera alone reads
   lying fire while another track within ``beside_m`` (1.2 m) is read standing or sitting by
   two cameras in the same snapshot: such a read is most often an extra box of that person (a
   crouch seen lengthwise, a fragment) on a track of its own or on a track held where someone
   was. Two of the three false falls traced on a seed set through the chain were this, the
   person's own track 0.99-1.1 m away; the candidate only waits, so a fall beside a bystander
   fires once the second camera sees the body or the bystander steps away (no fall of 96 lost,
   one 0.3 s later). Nor does any snapshot fire while another track, seen now, reads standing
   for sure within ``stayed_m`` (0.5 m) of a place the candidate's track stood on in the
   ``max_drop_s`` before the candidate began: the person it followed is still up where it
   left them, and the track is a phantom pulled off them by a ghost pair of two cameras' boxes
   or a false box (two of the six false falls traced on four seed sets through the chain, the
   standing person on a new track 0.15-0.4 m from where the phantom stood; none of the six of
   two fresh seed sets was of this kind). Only a standing read counts (a crouch, or a lying
   body seen lengthwise, reads sitting), and the candidate only waits: the price is a fall
   right beside someone who stands still where the faller stood, reported once they crouch
   to help or step aside. Lying time is the time between two
   consecutive snapshots of the track that both read lying (or unknown: no evidence either way;
   a dropout between them counts, the person is still down); time around a sitting or standing
   read does not count, but neither does it reset the sum: a lying body seen lengthwise from a
   camera reads short and narrow, i.e. seated, for a while. Reading ``standing`` or ``sitting``
   without a break for ``clear_s`` drops the candidate: a crouch or a fast sit-down misread as
   lying for a moment gets up or stays seated.
3. **Cleared**: an active fall ends with ``fall_cleared`` when the track reads standing for
   ``clear_s`` without a break (``reason: stood_up``; sitting up on the floor is still a fall),
   or when it drops again as rule 1 says (up for ``min_standing_s`` since the fall, then lying
   within ``max_drop_s``: ``stood_up`` at once, and a new candidate: someone who gets up and
   falls again is a second fall; a seated read of a person standing unsteadily used to keep the
   first fall active through the second, which was never reported: one of the 96 falls of
   ``bench/results/falls.md``; "up since the fall" counts from the first standing read after
   the last lying one: up from the floor through sitting, the streak used to run on from before
   the first fall, and a second fall two cameras read lying for 4 s had no event, one of 120
   held-out falls), or when the track has been absent from the snapshots for
   ``lost_s`` (``reason: lost``: the tracker gave the id up; a person lying still is served
   through detector dropouts for the tracker's ``hold_still_s``, so this is rare and long).
   **3b. Up on a new track**: the fall also ends (``stood_up``) when no camera sees its track
   now and a track born within ``handover_m`` of it after its last lying read, seen now, has
   read standing for ``clear_s``. The tracker holds a still person's track at their place
   while unseen, and one who gets up and walks straight off, seen by one camera at first, is
   not taken back from it: their walk becomes a new track a metre on, and the fall stayed
   active on the held track for ``lost_s`` (the demo's fall scene, ``tests/e2e/test_falls.py``,
   once the lying floor point moved on 2026-12-06). The price: someone unseen on the floor
   while a person whose track is born beside them stands there for ``clear_s`` is taken as up.

Why so short a wait: a fall is to be *reported* within 3 s of the body reaching the floor (issue
27's target), so the rule can only look at the first 1-2 s down; the longer "still down after
N s" question is what ``fall_cleared`` answers afterwards (a person who gets up clears the fall,
and a client that wants to wait longer before alarming can hold the event that long itself).
Until 2026-12-03 the rule waited ``lying_s`` = 10 s, which no fall could meet. The posture
confidence (the track's smoothed share of lying evidence,
:class:`service.tracking.posture.PostureSmoother`) is what a 1-2 s look has besides the label:
the gate cut the simulated false falls from 20 to 12 in 36 person-hours, for two falls in 48
reported late. It did not separate a crouch, whose box below 0.45 of a standing height read
lying in every view: since 2026-12-04 the posture reads such a compact box as sitting
(:mod:`service.tracking.posture`): with each person's own boxes the simulated false falls are
0-1 in 36 person-hours. Through the serving chain they were 34 per 24 person-hours, from
mispaired and false boxes fed to coasting or newborn tracks (rule 1's two conditions since
2026-12-05: 8 per 24 person-hours; with rule 2's reach and stale-candidate bounds, 5 per 24
person-hours over four seeds, two of them fresh). Most falls reported late or missed are
bodies no box (nor its keypoints, nor where its track was:
:mod:`service.tracking.posture_continuity`) reads lying, or that no camera sees down
(``bench/results/falls.md``). The rest read lying on and off (a lone camera's lengthwise view
reads seated between lying reads) and took more than 3 s to sum 1.5 s of lying. Since
2026-12-07 ``lying_s`` is 1.3 s: on the ten seed sets it reported three more of 240 falls in
time and three more of 120 fresh ones, with no more false falls in 60 person-hours of daily
life; 1.2 s added a false fall, 1 s three (crouches read lying for a second, a phantom held
on a false box), and a lower ``min_confidence`` (0.7) with 1 s one more (same file).

A track absent from a snapshot is neither evidence of getting up nor of staying down: its
candidate waits (dropouts while lying do not reset it) and fires on the next snapshot with it,
unless no camera has seen it lying for ``lying_gap_s``.

Rejected: a vertical speed of the head or the box top (needs a calibrated height per pixel
and jitters with the detector's box), requiring the person to be still while down (a fallen
person may move, trying to get up), and an unbroken lying streak (a lengthwise view's seated
reads would restart it, late past the 3 s).

Event JSON (on ``WS /v1/events`` and MQTT ``{base}/{room}/events``, with the zone events; ``seq``
is the events stream's, given by :class:`service.outputs.zone_monitor.ZoneMonitor`)::

    {"v": 1, "seq": 9, "type": "fall", "id": 3, "t": 1732390031.2, "since": 1732390029.6,
     "x": 2.51, "y": 1.18, "zones": ["kitchen"], "falls": [3]}
    {"v": 1, "seq": 10, "type": "fall_cleared", "id": 3, "t": 1732390102.5,
     "since": 1732390031.2, "reason": "stood_up", "duration_s": 71.3, "x": 2.6, "y": 1.2,
     "zones": ["kitchen"], "falls": []}

``since`` of a fall is the capture time of the first lying snapshot, of a clearing the fall's
``t``; ``zones`` the zones whose polygon holds the position (no hysteresis); ``falls`` the ids
with an active fall after the event (the room's fall state).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from service.outputs.zones import EVENT_VERSION, Zone

FALL, FALL_CLEARED = "fall", "fall_cleared"
ON_THE_BODY_S = 0.5  # a donor seen lying this recently still tracks the body (rule 1b)
STANDING, SITTING, LYING = "standing", "sitting", "lying"


@dataclass(frozen=True)
class FallRules:
    """The timings of the rules in the module docstring (seconds of capture time)."""

    max_drop_s: float = 2.0
    lying_s: float = 1.3
    clear_s: float = 3.0
    lost_s: float = 120.0
    min_confidence: float = 0.7
    standing_confidence: float = 0.75
    min_standing_s: float = 1.5
    handover_m: float = 1.5
    reach_m: float = 1.0
    lying_gap_s: float = 5.0
    beside_m: float = 1.2
    stayed_m: float = 0.5
    upright_unseen_s: float = 2.0
    coast_s: float = 1.0


@dataclass
class _Person:
    x: float
    y: float
    seen: float  # capture time of the last snapshot with this id
    born: float  # capture time of the first snapshot with this id
    born_x: float = 0.0  # where that was (rule 3b)
    born_y: float = 0.0
    measured: float | None = None  # ... of the last snapshot a camera saw it in (not coasting)
    stood_x: float = 0.0  # where the last standing read was
    stood_y: float = 0.0
    upright_at: float | None = None  # the last snapshot that read standing or sitting
    handed_over: bool = False  # its fall went to another track (rules 1b, 1c): no own event
    stood_sure: float = 1.0  # the posture confidence of the last standing read
    stood_sure_at: float | None = None  # the last standing read standing_confidence sure
    last_standing: float | None = None  # last snapshot that read standing
    stood_from: float | None = None  # first standing read of the upright streak (standing, or
    # sitting and standing) that last_standing ends: a sit-stand-fall counts the whole streak
    standing_since: float | None = None  # start of the current unbroken standing streak
    upright_since: float | None = None  # ... of standing or sitting (not lying)
    lying_since: float | None = None  # the candidate's start (rule 1)
    down_s: float = 0.0  # the candidate's lying time so far (rule 2)
    down_at: float | None = None  # the last snapshot that read lying or unknown (else None)
    lying_at: float = 0.0  # the last snapshot a camera saw lying
    drop_x: float = 0.0  # where the candidate's person last stood (rule 2's reach)
    drop_y: float = 0.0
    fallen_at: float | None = None  # the fall event's t while the fall is active
    stood_path: list[tuple[float, float, float]] = field(default_factory=list)  # (t, x, y) of
    # the seen standing reads of the last max_drop_s
    drop_path: tuple[tuple[float, float], ...] = ()  # ... before the candidate began (stayed_m)
    donor: int | None = None  # the track whose drop rule 1b handed this candidate (its id)
    sure_at: float | None = None  # the last seen snapshot, if it read lying for sure (rule 2)
    sure_both_at: float | None = None  # the last sure lying snapshot two cameras saw

    def stood_at(self, t: float, span_s: float) -> tuple[tuple[float, float], ...]:
        """Where the seen standing reads of the ``span_s`` before ``t`` were."""
        return tuple((x, y) for at, x, y in self.stood_path if t - at <= span_s)


class FallDetector:
    """Per-track fall state; ``update`` returns the events one snapshot confirms."""

    def __init__(self, rules: FallRules | None = None, zones: Sequence[Zone] = ()) -> None:
        self.rules = rules or FallRules()
        self.zones = list(zones)
        self._people: dict[int, _Person] = {}
        self._upright: list[tuple[int, float, float]] = []  # this snapshot's (rule 2)
        self._standing: list[tuple[int, float, float]] = []  # ... sure standing (stayed_m)
        self._present: set[int] = set()  # this snapshot's ids (rule 1c)
        self._measured: set[int] = set()  # ... that a camera sees
        self.last_t: float | None = None
        self.changed_t: float | None = None  # capture time of the last fall or clearing

    @property
    def active(self) -> list[int]:
        """Ids with an active fall."""
        return sorted(pid for pid, p in self._people.items() if p.fallen_at is not None)

    def state(self) -> dict[str, Any]:
        """The room's fall state: ``{"active", "ids", "t"}`` (MQTT ``{base}/{room}/fall``)."""
        ids = self.active
        return {"active": bool(ids), "ids": ids, "t": self.changed_t}

    def update(self, t: float, people: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
        """Advance to capture time ``t`` with the snapshot's people (id, x, y, posture)."""
        if self.last_t is not None and t < self.last_t:
            t = self.last_t  # never let time run backwards (a looped recording)
        self.last_t = t
        events: list[dict[str, Any]] = []
        people = list(people)
        self._present = {int(q["id"]) for q in people}
        self._measured = {int(q["id"]) for q in people if _measured(q)}
        self._upright = [
            (int(q["id"]), float(q["x"]), float(q["y"]))
            for q in people
            if q.get("posture") in (STANDING, SITTING) and len(q.get("cameras") or ()) >= 2
        ]
        self._standing = [
            (int(q["id"]), float(q["x"]), float(q["y"]))
            for q in people
            if q.get("posture") == STANDING
            and _measured(q)
            and _confidence(q) >= self.rules.standing_confidence
        ]
        self._drop_ghosts()
        for p in people:
            pid = int(p["id"])
            person = self._people.get(pid)
            if person is None:
                x, y = float(p["x"]), float(p["y"])
                person = self._people[pid] = _Person(x, y, t, t, x, y)
            person.x, person.y, person.seen = float(p["x"]), float(p["y"]), t
            events += self._observe(pid, person, t, p)
        for pid, person in self._people.items():
            if person.fallen_at is not None and self._up_elsewhere(pid, person, t):
                events.append(self._clear(pid, person, t, "stood_up"))
        for pid, person in list(self._people.items()):
            if t - person.seen < self.rules.lost_s:
                continue
            if person.fallen_at is not None:
                events.append(self._clear(pid, person, t, "lost"))
            del self._people[pid]
        return events

    def _observe(
        self, pid: int, p: _Person, t: float, person: Mapping[str, Any]
    ) -> list[dict[str, Any]]:
        rules = self.rules
        events: list[dict[str, Any]] = []
        # a track no camera sees now (coasting: ``cameras`` empty) carries its last posture,
        # which is no evidence of what the person does now (rule 1)
        seen = _measured(person)
        if seen and p.measured is not None and t - p.measured > rules.upright_unseen_s:
            p.upright_since = p.stood_from = None  # back after a long coast: a new streak
        if seen:
            p.measured = t
        posture = person.get("posture") if seen else None
        if posture in (STANDING, SITTING):
            p.upright_at = t
        if posture == STANDING:
            if (
                p.last_standing is None
                or p.stood_from is None
                or p.upright_since is None
                or p.lying_at > p.last_standing  # up from the floor (through sitting or not)
            ):
                p.stood_from = t  # a new upright streak
            p.last_standing = t
            p.stood_x, p.stood_y = p.x, p.y
            p.stood_path = [r for r in p.stood_path if t - r[0] <= rules.max_drop_s]
            p.stood_path.append((t, p.x, p.y))
            p.stood_sure = _confidence(person)
            if p.stood_sure >= rules.standing_confidence:
                p.stood_sure_at = t
            p.handed_over = False  # a person standing again: their own falls count again
            p.standing_since = t if p.standing_since is None else p.standing_since
            p.upright_since = t if p.upright_since is None else p.upright_since
            p.down_at = None
        elif posture == SITTING:
            p.standing_since = None
            p.upright_since = t if p.upright_since is None else p.upright_since
            p.down_at = None
        else:  # lying, or unknown (absent field): no evidence, the upright streaks stand
            if posture == LYING:
                p.standing_since = p.upright_since = None
                p.lying_at = t
                quick = (
                    p.last_standing is not None
                    and p.stood_from is not None
                    and t - p.last_standing <= rules.max_drop_s
                    and p.stood_sure_at is not None
                    and t - p.stood_sure_at <= rules.max_drop_s
                    and p.last_standing - p.stood_from >= rules.min_standing_s - 1e-9
                )
                up_since_fall = p.fallen_at is not None and (p.stood_from or 0.0) > p.fallen_at
                if quick and up_since_fall:
                    events.append(self._clear(pid, p, t, "stood_up"))  # up, and down again
                free = p.lying_since is None and p.fallen_at is None and not p.handed_over
                if free and quick:
                    p.lying_since, p.down_s, p.drop_x, p.drop_y = t, 0.0, p.stood_x, p.stood_y
                    p.drop_path, p.donor = p.stood_at(t, rules.max_drop_s), None
                elif free and p.last_standing is None and self._take_over(pid, p, t):
                    p.lying_since, p.down_s = t, 0.0
                elif p.lying_since is None:
                    donor = self._lost_candidate(pid, p, t)
                    if donor is not None:  # rule 1c: the body went to this track
                        if p.fallen_at is not None:  # up and down again
                            events.append(self._clear(pid, p, t, "stood_up"))
                        p.handed_over = False  # a track that gave its fall away takes it back
                        p.lying_since, p.down_s = donor.lying_since, donor.down_s
                        p.drop_x, p.drop_y = donor.drop_x, donor.drop_y
                        p.drop_path, p.donor = donor.drop_path, donor.donor
                        donor.handed_over, donor.lying_since = True, None
            if p.lying_since is not None and p.down_at is not None:
                p.down_s += t - p.down_at
            p.down_at = t
        if p.fallen_at is not None:
            if p.standing_since is not None and t - p.standing_since >= rules.clear_s:
                events.append(self._clear(pid, p, t, "stood_up"))
            return events
        if p.lying_since is None or p.handed_over:
            return events
        if t - p.lying_at > rules.lying_gap_s:
            p.lying_since = None  # no lying read for long: a stale candidate (rule 2)
            return events
        if p.upright_since is not None:
            if t - p.upright_since >= rules.clear_s:
                p.lying_since = None  # got up or sat: not a fall
            return events
        placed = (
            math.hypot(p.x - p.drop_x, p.y - p.drop_y) <= rules.reach_m
            and not self._beside_upright(pid, p, person)
            and not self._still_standing_there(pid, p)
        )
        if seen:
            sure = placed and posture == LYING and _confidence(person) >= rules.min_confidence
            p.sure_at = t if sure else None
            if sure and len(person.get("cameras") or ()) >= 2:
                p.sure_both_at = t
        else:  # a dropout right after sure lying reads that two cameras agreed on (rule 2)
            sure = (
                placed
                and p.sure_at is not None
                and t - p.sure_at <= rules.coast_s
                and p.sure_both_at is not None
                and p.sure_both_at >= p.lying_since
            )
        if p.down_s >= rules.lying_s - 1e-9 and sure:
            events.append(self._fall(pid, p, t))
        return events

    def _drop_ghosts(self) -> None:
        """Rule 1b's donor up: a candidate whose donor two cameras see standing or sitting
        now is dropped (module docstring)."""
        upright = {other for other, _, _ in self._upright}
        for p in self._people.values():
            if p.lying_since is not None and p.donor is not None and p.donor in upright:
                p.lying_since = p.donor = None

    def _beside_upright(self, pid: int, p: _Person, person: Mapping[str, Any]) -> bool:
        """Rule 2's lone view: ``person`` is read lying by one camera alone within
        ``beside_m`` of another track two cameras see standing or sitting now."""
        cameras = person.get("cameras")
        if self.rules.beside_m <= 0 or cameras is None or len(cameras) != 1:
            return False
        return any(
            other != pid and math.hypot(x - p.x, y - p.y) <= self.rules.beside_m
            for other, x, y in self._upright
        )

    def _still_standing_there(self, pid: int, p: _Person) -> bool:
        """Rule 2's stayed stander: another track reads standing (surely, seen now) within
        ``stayed_m`` of a place ``p`` stood on in the ``max_drop_s`` before its candidate."""
        if self.rules.stayed_m <= 0:
            return False
        return any(
            other != pid and math.hypot(x - sx, y - sy) <= self.rules.stayed_m
            for other, x, y in self._standing
            for sx, sy in p.drop_path
        )

    def _up_elsewhere(self, pid: int, p: _Person, t: float) -> bool:
        """Rule 3b: no camera sees the fallen track ``p`` now, and a track born within
        ``handover_m`` of it after its last lying read, seen now, has read standing for
        ``clear_s``: the person got up on a new id (module docstring)."""
        rules = self.rules
        if rules.handover_m <= 0 or pid in self._measured:
            return False
        return any(
            other != pid
            and other in self._measured
            and d.born > p.lying_at
            and d.standing_since is not None
            and t - d.standing_since >= rules.clear_s
            and math.hypot(d.born_x - p.x, d.born_y - p.y) <= rules.handover_m
            for other, d in self._people.items()
        )

    def _take_over(self, pid: int, p: _Person, t: float) -> bool:
        """Rule 1b: whether the lying track ``p``, never seen standing, is a person whose own
        track lost them as they fell; if so that track hands its fall over to ``p``."""
        rules = self.rules
        if rules.handover_m <= 0:
            return False
        donor_id = self._nearest_id(
            (math.hypot(d.stood_x - p.x, d.stood_y - p.y), other)
            for other, d in self._people.items()
            if other != pid
            and not d.handed_over
            and d.fallen_at is None
            and d.last_standing is not None
            # the donor saw the drop: a candidate of its own, its last standing read unsure, or
            # no camera has seen it since that read (lost as the person went down)
            and (
                d.lying_since is not None
                or d.stood_sure < rules.standing_confidence
                or (d.measured is not None and d.measured <= d.last_standing)
            )
            and d.stood_from is not None
            and t - d.last_standing <= rules.max_drop_s
            and d.last_standing - d.stood_from >= rules.min_standing_s - 1e-9
            and (d.upright_at is None or d.upright_at <= p.born)
            and not _still_on_the_body(d, p, t)
        )
        if donor_id is None:
            return False
        donor = self._people[donor_id]
        p.drop_x, p.drop_y = donor.stood_x, donor.stood_y
        p.drop_path = (
            donor.drop_path
            if donor.lying_since is not None
            else donor.stood_at(t, rules.max_drop_s)
        )
        donor.handed_over, donor.lying_since = True, None
        p.donor = donor_id
        return True

    def _lost_candidate(self, pid: int, p: _Person, t: float) -> _Person | None:
        """Rule 1c: the nearest candidate within ``handover_m`` of ``p`` that no camera sees in
        this snapshot (absent, or coasting and not seen lying for ``ON_THE_BODY_S``: the tracker
        gave its body to ``p``), was last seen by one within ``max_drop_s`` and began after
        ``p``'s active fall, if any, and whose person last stood within ``reach_m`` of
        ``p``; or None."""
        rules = self.rules
        if rules.handover_m <= 0:
            return None
        nearest = self._nearest_id(
            (math.hypot(d.x - p.x, d.y - p.y), other)
            for other, d in self._people.items()
            if other != pid
            and d.lying_since is not None
            and not d.handed_over
            and (p.fallen_at is None or d.lying_since > p.fallen_at)
            and other not in self._measured
            and (other not in self._present or t - d.lying_at > ON_THE_BODY_S)
            and d.measured is not None
            and t - d.measured <= rules.max_drop_s
            and math.hypot(d.drop_x - p.x, d.drop_y - p.y) <= rules.reach_m
        )
        return None if nearest is None else self._people[nearest]

    def _nearest_id(self, gaps: Iterable[tuple[float, int]]) -> int | None:
        """The id of the smallest (gap, id) within ``handover_m``, or None."""
        near = [(gap, other) for gap, other in gaps if gap <= self.rules.handover_m]
        return min(near)[1] if near else None

    def _zones_at(self, p: _Person) -> list[str]:
        return [z.name for z in self.zones if z.contains(p.x, p.y)]

    def _fall(self, pid: int, p: _Person, t: float) -> dict[str, Any]:
        since, p.fallen_at, p.lying_since = p.lying_since, t, None
        self.changed_t = t
        return {"v": EVENT_VERSION, "type": FALL, "id": pid, "t": t, "since": since,
                "x": round(p.x, 3), "y": round(p.y, 3), "zones": self._zones_at(p),
                "falls": self.active}  # fmt: skip

    def _clear(self, pid: int, p: _Person, t: float, reason: str) -> dict[str, Any]:
        since, p.fallen_at = p.fallen_at, None
        self.changed_t = t
        return {"v": EVENT_VERSION, "type": FALL_CLEARED, "id": pid, "t": t, "since": since,
                "reason": reason, "duration_s": round(t - (since or t), 3),
                "x": round(p.x, 3), "y": round(p.y, 3), "zones": self._zones_at(p),
                "falls": self.active}  # fmt: skip


def _still_on_the_body(donor: _Person, newcomer: _Person, t: float) -> bool:
    """Rule 1b's exception: ``donor`` was seen lying a moment ago nearer where it stood than
    ``newcomer`` is: it is on the body and ``newcomer`` a second track of it."""
    if t - donor.lying_at > ON_THE_BODY_S:
        return False
    own = math.hypot(donor.x - donor.stood_x, donor.y - donor.stood_y)
    return own <= math.hypot(newcomer.x - donor.stood_x, newcomer.y - donor.stood_y)


def _measured(person: Mapping[str, Any]) -> bool:
    """Whether a camera sees ``person`` in the snapshot (a coasting track's ``cameras`` is
    empty; a person without the field counts as seen)."""
    cameras = person.get("cameras")
    return cameras is None or len(cameras) > 0


def _confidence(person: Mapping[str, Any]) -> float:
    """The posture's confidence (a person without the field: sure, as the posture is all a
    client without confidences gives)."""
    value = person.get("posture_confidence")
    return 1.0 if value is None else float(value)
