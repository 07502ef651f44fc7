"""DESCEND's target source: ``ObjectTarget``'s height lowered at ``descend_speed`` only while the fix is fresh and
the filter converged; otherwise back up to the safety height, so the vehicle is never below it without a fresh
converged fix. The final part, right over the object, and its blind last half metre: see ``DescendTarget``.
"""

from __future__ import annotations

import math

from app.messages import TargetState, Vec3
from app.missions.estimates import Estimates
from app.missions.pickup import PickupEstimates
from app.missions.pickup_targets import ObjectTarget, Telemetry

FIX_TIME_TOLERANCE_S = 1e-6  # a fix's time read back as now − its age: the same fix within rounding
# The radar saw the water closer than the crest clearance and then nothing: the crest rose into its first range
# (0.4 m), closer still. For this long after that close height, it is taken as the water's (at most) and keeps
# lifting the vehicle: dropping the lift there let a waiting vehicle sink back into the crest (README, *Evaluating*).
CLOSE_WATER_HOLD_S = 1.0


class DescendTarget(ObjectTarget):
    """Down at ``speed_mps`` over the object while the fix is fresh and the filter converged; else back up to
    (and waiting at) ``safety_height_m`` — a final descent turned back so is given up (``final_descent_given_up``),
    as one that went blind or drifted off the object: water met on the way up is no place to grab.

    The final part — below ``final_height_m``, raised to clear the highest recent crest by ``crest_margin_m``
    (``MeanSeaLevel.crest_m``: a vehicle waiting lower is met by a crest wherever it is) — is flown only right
    over the object: it starts within ``final_radius_m`` of the estimate, moving with it (relative horizontal speed
    at most ``final_max_speed_mps``: a vehicle that lags the object's wave orbit slides off it on the way down)
    and, with ``final_start_max_rise_mps``, only while the water under it falls (never while the radar is silent
    right after seeing the water closer than ``crest_clearance_m``: a crest inside its first range); drifting past
    ``final_abort_radius_m`` — also where the lead has lifted its desired height above the final height —
    climbs back to the final height and waits again. The last half metre or so is flown
    blind (the camera's view there is smaller than the object's offset plus the tilt, and the estimate drifts off
    the object by decimetres a second): when no new fix has come for ``blind_gap_s``, the descent goes on only if
    the vehicle is then within ``final_radius_m`` of the estimate and moving with it, as at its start, and only
    if going on at ``speed_mps`` it reaches ``touchdown_height_m`` before its newest fix is older than ``fresh_s``
    and GRAB's sink from there (``grab_sink_s``) the water before it is older than ``grab_blind_max_s`` (else it
    would turn back at the bottom, where crests met it off the object) — else it climbs back to the final
    height while the camera can still see the object. Already after ``blind_pause_s`` without a new fix, a descent
    that could not go on blind stops going down (holds its desired height): the fixes come back (on down) or the
    gap passes and it climbs back from higher and slower than it would have — turning back at ``speed_mps``, the
    rising water met it. The desired height never leads
    the vehicle's own height (over the mean sea) by more than ``max_lead_m``: a vehicle lagging its target
    would otherwise come down at the envelope's full speed; in the final part by no more than
    ``final_max_lead_m`` (0.5 m of lead there asked for 1 m/s down, and an ArduCopter coming down at that,
    accelerating upwards at about 1 m/s², sank on for up to 0.5 m when it had to climb back: into the water,
    off the object). Whenever it is not going down onto the object (waiting for the final part, climbing back), a
    crest that the radar sees rising under it closer than ``crest_clearance_m`` lifts it: waiting at the final
    height, a crest above the highest of the last minute reached it, and climbing back from low down, the water
    rose faster than the vehicle. Going down on a fresh converged fix over an object drifting no faster than
    ``precise_max_drift_mps``, its target asks guidance for precision (``TargetState.precise``: the position loop
    at a gain of 10 1/s and a 0.4 s lead on PX4, 6.7 1/s on ArduPilot, instead of 5; ``guidance.<autopilot>``): the
    vehicle lagged the object's wave orbit by up to 0.15 m there, and where it lags it meets the water."""

    name = "descend"

    def __init__(
        self,
        model: PickupEstimates,
        telemetry: Telemetry,
        start_height_m: float,
        speed_mps: float,
        safety_height_m: float,
        fresh_s: float,
        converged_s: float,
        final_height_m: float = 0.0,
        final_radius_m: float = math.inf,
        final_abort_radius_m: float = math.inf,
        crest_margin_m: float = 0.0,
        max_lead_m: float = math.inf,
        final_max_speed_mps: float = math.inf,
        blind_gap_s: float = math.inf,
        final_max_lead_m: float = math.inf,
        crest_clearance_m: float = 0.0,
        lean_yaw_min_tilt_rad: float | None = None,
        precise_max_drift_mps: float = math.inf,
        touchdown_height_m: float | None = None,
        final_start_max_rise_mps: float = math.inf,
        blind_pause_s: float = math.inf,
        grab_sink_s: float = 0.0,
        grab_blind_max_s: float = math.inf,
    ) -> None:
        super().__init__(model, telemetry, start_height_m, lean_yaw_min_tilt_rad)
        self.final_start_max_rise_mps = final_start_max_rise_mps
        self.precise_max_drift_mps = precise_max_drift_mps
        self.touchdown_height_m = touchdown_height_m
        self.speed_mps = speed_mps
        self.safety_height_m = safety_height_m
        self.fresh_s = fresh_s
        self.converged_s = converged_s
        self.final_height_m = final_height_m
        self.final_radius_m = final_radius_m
        self.final_abort_radius_m = max(final_abort_radius_m, final_radius_m)
        self.crest_margin_m = crest_margin_m
        self.max_lead_m = max_lead_m
        self.final_max_speed_mps = final_max_speed_mps
        self.blind_gap_s = blind_gap_s
        self.blind_pause_s = blind_pause_s
        self.grab_sink_s = grab_sink_s
        self.grab_blind_max_s = grab_blind_max_s
        self.final_max_lead_m = min(final_max_lead_m, max_lead_m)
        self.crest_clearance_m = crest_clearance_m
        self.waits = 0  # ticks the final descent waited for the vehicle to come over the object
        self.go_arounds = 0  # final descents given up for drifting off the object
        self.plunging = False  # in the final part, right over the object
        self.blind_go_arounds = 0  # final descents given up for going blind off the object
        self._committed = False  # this final descent went on blind, right over the object
        self._fix_t_s: float | None = None  # the newest fix (its capture time) …
        self._fix_seen_s = -math.inf  # … and when it was first seen here
        self._t_s: float | None = None
        self._close_water: tuple[float, float] | None = None  # (t_s, m): the radar's newest height under the clearance
        model.final_descent_given_up = False
        model.grab_gone_blind = model.grab_gone_off = False  # (set by a GRAB that gave up; GRAB comes only from here)

    def final_height_now_m(self) -> float:
        return max(self.final_height_m, self.model.sea_level.crest_m() + self.crest_margin_m)

    def target_at(self, t_s: float) -> TargetState | None:
        dt_s = 0.0 if self._t_s is None else max(0.0, t_s - self._t_s)
        self._t_s = t_s
        snap = self.model.snapshot(t_s)
        fix_t_s = None if snap.fix_age_s is None else t_s - snap.fix_age_s
        if fix_t_s is not None and (self._fix_t_s is None or abs(fix_t_s - self._fix_t_s) > FIX_TIME_TOLERANCE_S):
            self._fix_t_s, self._fix_seen_s = fix_t_s, t_s
        # DESCEND was entered after ``converged_s`` of convergence; going on down needs a fresh fix and a
        # filter that is converged now
        good = snap.fix_age_s is not None and snap.fix_age_s <= self.fresh_s and snap.converged_for_s is not None
        # and the sea is known: the radar sees it, or (under its first range, near the water) its mean level
        # was tracked moments ago
        good = good and (snap.height_above_sea_m is not None or snap.height_over_mean_sea_m is not None)
        final_m = self.final_height_now_m()
        before_m, was_going_down = self.height_m, self.plunging and not self._committed
        if not good:  # climb back to (and wait at) the safety height
            if self.plunging:  # a final descent turned back (its fix stale): water met on the way up is no
                self.model.final_descent_given_up = True  # place to grab (the guards), as after going blind
            self.height_m = max(self.height_m, self.safety_height_m)
            self.plunging = False
        elif self.height_m <= final_m or self.plunging:
            # (a final descent whose desired height the lead lifted over the final height — a vehicle rising with a
            # crest — is still one: drifting off the object there turns it back too)
            off_m, slip_mps = self._off_the_object(t_s)
            over_it = off_m <= self.final_radius_m and slip_mps <= self.final_max_speed_mps
            seeing = t_s - self._fix_seen_s <= self.blind_gap_s
            if self.plunging and not self._committed and not seeing:
                # going blind: on only right over the object, and only if the water is reached on a fresh fix
                self._committed = over_it and self._reaches_the_water_fresh(snap)
                if not self._committed:
                    self.plunging = False
                    self.blind_go_arounds += 1
                    self.model.final_descent_given_up = True
            if self.plunging and off_m > self.final_abort_radius_m:
                self.plunging = False
                self.go_arounds += 1
                self.model.final_descent_given_up = True
            elif not self.plunging and over_it and seeing and self._water_not_rising(t_s, snap):
                # (a stale estimate starts no final descent)
                self.plunging, self._committed = True, False
                self.model.final_descent_given_up = False
            if self.plunging:
                self.height_m = max(0.0, self.height_m - self.speed_mps * dt_s)
            else:
                self.waits += 1  # the last part only right over the object: wait at the final height until it is
                self.height_m = final_m
        elif self._off_the_object(t_s)[0] <= self.final_abort_radius_m:
            self.height_m = max(final_m, self.height_m - self.speed_mps * dt_s)
        else:  # off the object on the way down too: hold the height until guidance has caught up with it
            self.waits += 1
        if was_going_down and self.height_m < before_m and self._pausing(t_s, snap):
            self.height_m = before_m  # blind a while, and it could not go on blind: no lower for now
        vehicle_m = snap.height_over_mean_sea_m
        lead_m = self.final_max_lead_m if self.height_m < final_m else self.max_lead_m
        if vehicle_m is not None and self.height_m < vehicle_m - lead_m:
            self.height_m = vehicle_m - lead_m  # not far ahead of the vehicle on the way down
        # aim at the object now, its velocity fed forward: aiming at a prediction of it at touchdown (up to 1 s
        # ahead) put the vehicle up to half a wave orbit off and lost the marker low (sea state 2: 0 of 3
        # seeds picked up with the lead, 20 of 20 without)
        # going down on a fresh fix, guidance follows the object as tightly as the autopilot allows (sea state 2, 80
        # runs in process: 3 touchdowns over 0.10 m off, 8 before, 5 with it from the final height only) — but not
        # over a fast drift, where its tilt swings took the object out of a leaning vehicle's view (README)
        precise = good and self._drift_mps(t_s) <= self.precise_max_drift_mps
        return self._aim(t_s, self._clear_of_crests(t_s, self.height_m, vehicle_m, snap.height_above_sea_m), precise)

    def _pausing(self, t_s: float, snap: Estimates) -> bool:
        """Going down in the final part, not committed to the blind last part, ``blind_pause_s`` without a new fix,
        and not able to go on blind (``_reaches_the_water_fresh``): no lower for now."""
        unseen_s = t_s - self._fix_seen_s
        going_down = self.plunging and not self._committed
        return going_down and unseen_s > self.blind_pause_s and not self._reaches_the_water_fresh(snap)

    def _reaches_the_water_fresh(self, snap: Estimates) -> bool:
        """Would the vehicle, going on down at ``speed_mps``, reach the touchdown height (over the water the radar
        sees, else over the mean sea) while the newest fix is still fresh (``fresh_s``), and GRAB's sink from there
        (``grab_sink_s``) reach the water before that fix is ``grab_blind_max_s`` old? A blind descent that cannot
        climbs back once its fix is stale, or GRAB gives it up on the way down (sea state 3, seed 10 run 130: given
        up 0.2 m over the mean sea still sinking, it met the water 0.30 m off the object) — at the bottom, where a
        crest meets it off the object. Without a ``touchdown_height_m``: yes."""
        if self.touchdown_height_m is None or snap.fix_age_s is None:
            return True
        over_m = snap.height_above_sea_m if snap.height_above_sea_m is not None else snap.height_over_mean_sea_m
        if over_m is None:
            return True
        at_touchdown_s = snap.fix_age_s + max(0.0, over_m - self.touchdown_height_m) / self.speed_mps
        return at_touchdown_s <= self.fresh_s and at_touchdown_s + self.grab_sink_s <= self.grab_blind_max_s

    def _water_not_rising(self, t_s: float, snap: Estimates) -> bool:
        """The water under the vehicle rises no faster than ``final_start_max_rise_mps`` (or the radar cannot
        tell): going down behind falling water, the vehicle meets it lower, as it rises again; going down as a
        crest rose, it met the crest high (0.4–0.9 m over the mean), where the object's orbit moves it fastest,
        just after the camera had lost it (sea state 3: 5 of 103 such contacts off the object, 0 of 255 on
        crests lower than 0.4 m; README, *Evaluating*). A radar gone silent right after a height closer than
        ``crest_clearance_m`` is no "cannot tell": the crest has risen inside its first range (the rate is
        unknown because the water is that close), and a final descent started there met it 0.27–0.28 m off."""
        if snap.height_above_sea_m is None and self._water_held_close(t_s):
            return False
        rise = self.model.sea_level.rise_rate_mps(t_s)
        return rise is None or rise <= self.final_start_max_rise_mps

    def _drift_mps(self, t_s: float) -> float:
        """How fast the object drifts (the filter's mean drift, without the waves), m/s; inf when unknown."""
        drifted = self.model.drifted(t_s)
        return math.inf if drifted is None else math.hypot(*drifted[1])

    def _clear_of_crests(self, t_s: float, height_m: float, vehicle_m: float | None, radar_m: float | None) -> float:
        """The height to aim at this tick: ``height_m``, raised while the vehicle is not going down onto the object
        and the radar sees the water under it closer than ``crest_clearance_m`` (a crest rising under it lifts it;
        the next tick aims at ``height_m`` again). The radar seeing nothing within ``CLOSE_WATER_HOLD_S`` of such a
        close height means the crest came closer than its first range: that height stands in for the water's."""
        if radar_m is not None:
            self._close_water = (t_s, radar_m) if radar_m < self.crest_clearance_m else None
        elif self._water_held_close(t_s):
            radar_m = self._close_water[1]  # type: ignore[index]
        if self.plunging or radar_m is None or vehicle_m is None or radar_m >= self.crest_clearance_m:
            return height_m
        return max(height_m, vehicle_m + self.crest_clearance_m - radar_m)

    def _water_held_close(self, t_s: float) -> bool:
        """The radar saw the water closer than ``crest_clearance_m`` within ``CLOSE_WATER_HOLD_S`` (and nothing
        farther since): while it is silent, the water is taken to be that close, or closer."""
        return self._close_water is not None and t_s - self._close_water[0] <= CLOSE_WATER_HOLD_S

    def _off_the_object(self, t_s: float) -> tuple[float, float]:
        """How far the vehicle is off the estimate (m, horizontal) and how fast it moves relative to it (m/s)."""
        pv, est = self.telemetry().pos_vel, self.model.estimate(t_s)
        if pv is None or est is None:
            return math.inf, math.inf
        slip = horizontal_distance_m(pv.vel_ned_mps, est.vel_ned_mps)
        return horizontal_distance_m(pv.pos_ned_m, est.pos_ned_m), slip


def horizontal_distance_m(a: Vec3, b: Vec3) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])
