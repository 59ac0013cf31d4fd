"""Tunables of the scripted experts, read from a scenario's ``expert`` section: :func:`expert_config`.

The env never reads these; they are the experts' controller gains, margins and timeouts, owned by
the expert (the ``Scenario`` keeps the YAML section as a plain mapping), documented, validated
(a ``ConfigError`` naming the file and the ``expert.*`` key when an expert is built) and reachable
from YAML:

.. code-block:: yaml

    expert:
      leader_speed: 0.8
      sonar_fix: {stale_after: 6.0}
      navigator: {max_axis: 0.3}
"""

from __future__ import annotations

from dataclasses import dataclass, field

from parcover_env.config import Scenario, from_mapping
from parcover_env.config.checks import check, positive

__all__ = ["ExpertConfig", "NavigatorConfig", "SonarFixConfig", "expert_config"]


@dataclass(frozen=True)
class SonarFixConfig:
    """Sonar fixes of leaders out of Kinect view (``localization: both``; Min et al. + Kim, Pearce & Amato)."""

    stale_after: float = 8.0
    """A leader whose last Kinect fix is older than this stops to scan (s)."""
    rescan_distance: float = 2.0
    """A leader scans again only after driving this far since its last scan (m)..."""
    final_rescan_distance: float = 0.2
    """... or this far when it believes it is at its route's end, so that an arrival on drifted
    odometry is checked, and corrected until a scan confirms it (m)."""
    scan_rate: float = 0.6
    """Turn rate while scanning (rad/s), capped at the robot's ``max_turn_rate``."""
    stop_speed: float = 0.005
    """A leader due for a scan brakes first and starts turning once its encoder speed is below this
    (m/s): with the drive's acceleration limit it rolls on for several centimetres after the stop
    command, and a scan started while rolling is pinned to where the stop was commanded, which
    shifts every fix forward along the route."""
    gate_distance: float = 0.15
    """Floor of the fix gate (m): the belief's position covariance is widened by
    (``gate_distance`` / ``gate_sigmas``)^2 in every direction, so that right after a fix, when the
    covariance is tiny, a fix this far away is still believed (the localizer's own error)."""
    gate_sigmas: float = 4.0
    """A fix is accepted only inside this many standard deviations of the belief's (widened) position
    covariance (Mahalanobis distance), and the localizer searches that ellipse (-). The covariance
    is the odometry's (observed, Chong & Kleeman) until a sonar fix, then the expert's own
    propagation from the fix: a gate along the covariance ellipse admits a drifted robot's true
    fix along the major axis without admitting false matches along the minor one (Kim, Pearce & Amato §3-4)."""
    gate_heading_deg: float = 15.0
    """A fix is accepted only within this heading of the belief... (deg): rooms are nearly
    symmetric, and a scan often matches the map turned by 90 or 180 degrees about a nearby point."""
    gate_heading_max_deg: float = 40.0
    """... plus ``gate_sigmas`` heading sigmas of the belief, at most this (deg); the localizer
    drops candidates outside the same gate."""
    confirm_distance: float = 0.2
    """A successful fix refused by the gate is remembered as a correction; a later fix that agrees with
    it (carried along by the odometry) within this distance and ``gate_heading_deg`` is accepted even
    outside the gate (m): the covariance cannot see pushes from contacts, two scans from different
    places agreeing can."""
    shift_test: float = 0.2
    """A fix is used only if the scan pins the pose down: shifted by this distance (m) in any of 8
    directions, the scan must match the known map worse by at least ``min_shift_increase``. A scan
    of open space (mostly no echo) or along a straight corridor matches about as well shifted, and
    the localizer's pose is then a guess along the free direction. 0 switches the test off."""
    min_shift_increase: float = 0.003
    """Smallest increase of the mean clipped scan error under that shift (m). Measured on generated
    maps 5, 24, 117, 120 and 146: fixes 0.16-0.40 m off showed 0.000 (+-0.002), good fixes mostly
    0.01-0.09, a few 0.004."""
    refused_rescans: int = 2
    """After a successful fix refused by the gate, or after any scan without an accepted fix at what
    it believes is its route's end (with the env's scans, ``observation.scan``: anywhere, as the
    env's next search region is wider; not after a held or uninformative one, ``relocate_distance``),
    the leader scans again at once (without driving
    ``rescan_distance`` first), up to this many times in a row: a second scan can confirm the refused
    fix (``confirm_distance``), or search the wider region of ``miss_inflation``, while the robot is
    still where it doubted its belief (-)."""
    miss_inflation: float = 2.0
    """Each scan without an accepted fix widens the next scan's gate and search region: its standard
    deviations are multiplied by this (-), until a fix. Contacts push robots unseen by the encoders,
    and a robot pushed outside its covariance is otherwise never found inside its search region."""
    max_inflation: float = 8.0
    """Largest total factor of ``miss_inflation`` (-): the search region stays bounded."""
    kpoi_check_distance: float = 0.6
    """A leader whose route point ahead is a KPOI and whose last fix is older than ``stale_after``
    stops and scans once when it believes that KPOI is this close (m; 0: never): the env's route
    follows its estimate and moves on once the estimate reaches the KPOI, so a drifted arrival at a
    KPOI is never corrected afterwards (the same reason as ``final_rescan_distance``)."""
    relocate_distance: float = 0.5
    """With the env's scans: after a scan whose fix is held for confirmation (``scan_result`` 0.5; the
    registered expert's env holds fixes found only in a widened region, ``scan.confirm_widened``, except
    for the sonar navigator's) or that was uninformative (-0.5), the leader does not scan again
    where it stands (a look-alike match
    repeats there, and an uninformative scene stays uninformative) but at the first place at least this
    far along its route, at most ``rescan_distance``, where the known map predicts an informative
    scan (:class:`~parcover_env.expert.scan_places.ScanPlaces`; none: after ``rescan_distance``); at
    its route's end (also reached before the place chosen ahead), at such a place back along its route
    in its sight, within ``rescan_distance`` or else farther back, and beyond the last such place whose
    scan gave no fix, then it returns (none: it scans no more). Short against ``rescan_distance``: a
    held fix may be right and the estimate wrong. 0: such scans count as rejected ones (m). After a
    second uninformative scan in a row the
    predicted places are not used until a fix: the next scans after an uninformative one are
    ``rescan_distance`` apart (the noise-free prediction is optimistic along corridors, where a real
    scan every ``relocate_distance`` stays uninformative); after a held one (the scene was
    informative) the predicted place is used, to confirm it soon. 0: off (the expert before
    2026-11-26). Measured with 0.5 m and ``confirm_widened`` on (``docs/lab/expert_benchmark.md``,
    2026-11-26): generated seeds 0-199 199 / 200 (off: 195 / 200), 200-299 98 / 100 (off: 97 / 100)."""
    stuck_time: float = 5.0
    """With ``relocate_distance`` > 0: a leader waiting to scan from elsewhere (after a held scan, or an
    uninformative one away from its route's end, where it stands still on purpose) whose belief has
    moved less than ``stuck_distance`` for this long (s; braked by a wall or a teammate, or backing off
    and driving in again) drives ``relocate_distance`` into the freest direction of its own sonar ring
    (or up to ``stop_margin`` before the shortest reading of that direction's front sector), then scans:
    a held fix is confirmed only by a scan from elsewhere, and an uninformative scene stays so. Longer
    than one give-way (``patience`` 2 s plus ``backoff_time`` 1 s) of the first robots, so that the
    usual back-off is tried first."""
    stuck_distance: float = 0.1
    """See ``stuck_time`` (m); half the env's ``shift_test`` (0.2 m), the move a confirming scan needs."""
    fix_sigma: float = 0.05
    """Position standard deviation of an accepted sonar fix along x and y (m): the covariance the
    expert propagates the corrected belief from."""
    fix_sigma_heading_deg: float = 2.0
    """Heading standard deviation of an accepted sonar fix (deg)."""
    follow_chain: bool = True
    """A follower that sees the robot ahead fuses, at every step, the pose that the camera measurement
    implies (the robot ahead's belief composed with the measured relative pose) into its own belief
    (a Kalman update with the chained covariance): Min et al.'s followers are localized relative to
    their leader, so a follower promoted at a split starts from its leader's accuracy instead of its
    own drifted, contact-pushed odometry. False: followers keep pure odometry until they lead."""
    calibrate_drift: bool = True
    """With the ``wheels`` odometry: the expert estimates each robot's heading drift per metre and per
    radian turned from the absolute headings it gets (env fixes, a follower's chained heading) and steers
    by the odometry calibrated with it (:mod:`~parcover_env.expert.odometry_drift`; our extension)."""

    def __post_init__(self) -> None:
        positive(self, "stale_after", "scan_rate", "stop_speed", "gate_distance", "gate_heading_deg", "gate_sigmas",
                 "fix_sigma", "fix_sigma_heading_deg", "confirm_distance")
        check(self.shift_test >= 0, "shift_test", f"must be >= 0, got {self.shift_test}")
        check(self.relocate_distance >= 0, "relocate_distance", f"must be >= 0, got {self.relocate_distance}")
        positive(self, "stuck_time", "stuck_distance")
        check(self.min_shift_increase >= 0, "min_shift_increase", f"must be >= 0, got {self.min_shift_increase}")
        check(self.miss_inflation >= 1, "miss_inflation", f"must be >= 1, got {self.miss_inflation}")
        check(self.max_inflation >= 1, "max_inflation", f"must be >= 1, got {self.max_inflation}")
        check(self.refused_rescans >= 0, "refused_rescans", f"must be >= 0, got {self.refused_rescans}")
        check(self.kpoi_check_distance >= 0, "kpoi_check_distance",
              f"must be >= 0, got {self.kpoi_check_distance}")
        check(self.rescan_distance >= 0, "rescan_distance", f"must be >= 0, got {self.rescan_distance}")
        check(self.final_rescan_distance >= 0, "final_rescan_distance",
              f"must be >= 0, got {self.final_rescan_distance}")
        for name in ("gate_heading_deg", "gate_heading_max_deg"):
            check(getattr(self, name) < 90, name,
                  f"must be < 90 (a gate that admits a quarter turn admits the symmetric false fixes), "
                  f"got {getattr(self, name)}")
        check(self.gate_heading_max_deg >= self.gate_heading_deg, "gate_heading_max_deg",
              f"must be >= gate_heading_deg ({self.gate_heading_deg}), got {self.gate_heading_max_deg}")


@dataclass(frozen=True)
class NavigatorConfig:
    """Kim, Pearce & Amato's NAVIGATOR (``localization: sonar``; :mod:`parcover_env.expert.navigator`)."""

    node_step: float = 0.05
    """Spacing of the path nodes scored as subgoal candidates (m)."""
    initial_axis: float = 0.05
    """Ellipse semi-axes at the start and after a fix (m)."""
    rate_distance: float = 0.05
    """Ellipse growth per metre travelled (m/m)."""
    rate_rotation: float = 0.03
    """Ellipse growth per radian turned (m/rad)."""
    max_axis: float = 0.35
    """The subgoal is chosen before the ellipse semi-axis exceeds this (m)."""
    min_advance: float = 0.6
    """A new team subgoal is at least this far along the route (m)."""
    tie_tol_deg: float = 5.0
    """Biases within this of the best count as equal; then the farthest node wins (deg)."""
    min_wall_length: float = 0.3
    """A feature (corner) is usable only if both its walls are at least this long (m)."""
    min_readings: int = 2
    """A wall counts as seen from a node if at least this many scan readings hit it near its normal."""
    min_walls_seen: int = 1
    """A feature is usable from a node if at least this many of its two walls are seen (0, 1 or 2)."""
    range_margin: float = 0.15
    """Features are looked for within the sonar's ``range_max`` minus this (m)."""
    max_shift: float = 0.6
    """Subgoal rearrangement (Kim, Pearce & Amato §3.2, §4) shift cap: farthest a rearranged subgoal
    moves along its path, an off-path (bisector) subgoal lies from its path, and a subgoal slides
    along the bisector to keep the robots apart (m). OUR EXTENSION: the paper bounds the move only
    by the legal space S_i and gives no cap (:mod:`parcover_env.expert.rearrange`)."""
    shift_step: float = 0.1
    """Bisector rearrangement: step of that slide along the bisector (m)."""
    separation_margin: float = 0.15
    """Robots at their subgoals stay at least 2 radius + this apart (m), and two subgoals closer than
    that are rearranged even when neither blocks the other's scan (the proximity trigger). OUR
    EXTENSION: the paper lets robots stand "close as long as they are not in collision" (§4) and
    rearranges only on blocking; the blocking threshold (a loss of 0.25 deg of scan angle) is ours
    too (:data:`parcover_env.expert.rearrange.RESOLUTION`)."""
    lookahead: float = 0.35
    """Pure-pursuit look-ahead distance along the path while driving to a subgoal (m)."""
    arrive_tol: float = 0.05
    """A robot has arrived at its subgoal within this distance (by its belief) (m)."""
    goal_tol: float = 0.1
    """A robot is done when a successful fix puts it within this of its route's end (m)."""
    max_final_scans: int = 3
    """A robot at its route's end stops after this many scans even without a good fix."""
    scan_rate: float = 0.5
    """Turn rate while scanning (rad/s); keep rate * dt below the 5 deg bin."""
    stop_speed: float = 0.005
    """The robot whose turn it is to scan starts turning once its encoder speed is below this (m/s):
    the last robot to arrive may still be rolling, and its scan would be pinned to where it was."""
    bin_tol_deg: float = 2.0
    """A scan bin is filled by a reading within this of its centre angle (deg)."""
    drive_timeout: float = 20.0
    """Extra seconds over the nominal driving time before a drive phase is cut short (s)."""
    stop_margin: float = 0.05
    """A robot stops when an obstacle ahead is within radius + this (m)..."""
    slow_margin: float = 0.25
    """... and slows down linearly from radius + this (m)."""
    front_sector_deg: float = 25.0
    """Sonar beams within this of straight ahead are the front beams used for braking (deg)."""
    side_sector_deg: float = 30.0
    """Sonar beams within this of +-90 deg are the side beams: a side echo closer than radius +
    ``slow_margin`` turns a driving robot away from it, at omega_max at radius + ``stop_margin`` (deg)."""
    sector_rule: int = 2
    """Visibility sector merge rule of the localizer's sectors (0 = none, 1 or 2, Kim, Pearce & Amato)."""
    teammates_in_map: bool = True
    """Localize against the known map plus the teammates' discs at their believed positions."""
    accept_error: float = 0.07
    """A fix is accepted when the mean clipped error between the scan and the synthetic scan of the known
    map *with the other robots' discs at their beliefs* is below this (m). The localizer's own
    success test sees teammates as unknown obstacles and rejects good poses next to them."""

    region_sigmas: float = 3.0
    """A scan is localized inside this many standard deviations of the belief's covariance
    (propagated from the last fix with the robot's odometry model), widened by the Kim, Pearce & Amato ellipse's
    semi-axis (-)."""
    mask_sigmas: float = 2.0
    """Navigator fixes rejected by both tests above are accepted when the scan matches the known map
    (mean clipped error below ``accept_error``) on the readings no teammate can explain: a reading
    shorter than the known map's is left out when it ends within radius + this many uncertainty
    radii of a teammate's belief (-). At the route's end robots stand side by side, and a teammate
    whose belief is off by more than its disc spoils both the plain and the team-map comparison."""
    min_unmasked_share: float = 0.5
    """... provided at least this share of the readings is left (-)."""

    def __post_init__(self) -> None:
        check(self.mask_sigmas >= 0, "mask_sigmas", f"must be >= 0, got {self.mask_sigmas}")
        check(0 < self.min_unmasked_share <= 1, "min_unmasked_share",
              f"must be in (0, 1], got {self.min_unmasked_share}")
        for name in ("region_sigmas", "node_step", "stop_speed", "rate_distance", "max_axis", "min_advance",
                     "lookahead", "arrive_tol", "goal_tol", "scan_rate", "bin_tol_deg", "shift_step", "initial_axis",
                     "accept_error", "front_sector_deg"):
            positive(self, name)
        for name in ("rate_rotation", "max_shift", "separation_margin", "drive_timeout", "min_wall_length",
                     "range_margin", "tie_tol_deg", "stop_margin"):
            check(getattr(self, name) >= 0, name, f"must be >= 0, got {getattr(self, name)}")
        check(self.sector_rule in (0, 1, 2), "sector_rule", f"must be 0, 1 or 2, got {self.sector_rule}")
        check(self.min_walls_seen in (0, 1, 2), "min_walls_seen", f"must be 0, 1 or 2, got {self.min_walls_seen}")
        check(self.min_readings >= 1, "min_readings", f"must be >= 1, got {self.min_readings}")
        check(self.max_final_scans >= 1, "max_final_scans", f"must be >= 1, got {self.max_final_scans}")
        check(self.initial_axis < self.max_axis, "initial_axis",
              f"must be < max_axis ({self.max_axis} m), got {self.initial_axis}")
        check(self.slow_margin > self.stop_margin, "slow_margin",
              f"must be > stop_margin ({self.stop_margin} m), got {self.slow_margin}")
        check(self.front_sector_deg <= 180, "front_sector_deg", f"must be <= 180, got {self.front_sector_deg}")
        check(0 <= self.side_sector_deg <= 90, "side_sector_deg", f"must be in [0, 90], got {self.side_sector_deg}")


@dataclass(frozen=True)
class ExpertConfig:
    """The scripted expert of Min et al. (leaders drive the plan, followers keep formation)."""

    leader_speed: float = 0.9
    """A leader with followers drives at this fraction of v_max so they can close gaps (-)."""
    stop_margin: float = 0.05
    """A leader stops when its front sonar sees something within radius + this (m)..."""
    slow_margin: float = 0.25
    """... and slows down linearly from radius + this (m)."""
    front_sector_deg: float = 25.0
    """Sonar beams within this of straight ahead are the front beams used for braking (deg)."""
    patience: float = 2.0
    """A leader braked (below 20 % speed) for longer than this backs off (s)..."""
    patience_stagger: float = 0.3
    """... plus this per robot index, so two robots never give way together (s)."""
    backoff_time: float = 1.0
    """How long a leader backs off (s)..."""
    backoff_speed: float = 0.4
    """... reversing at this fraction of v_max (-)..."""
    backoff_turn: float = 0.6
    """... while turning at this fraction of omega_max (-)."""
    search_speed: float = 0.6
    """A follower that lost sight of the robot ahead drives its own route at this fraction of v_max (-)."""
    follower_min_speed: float = -0.3
    """Slowest (most negative) speed of the l-psi follower, a fraction of v_max (-): it may back up
    a little to keep its distance."""
    alone_after: float = 3.0
    """A follower that has not seen the robot ahead for this long navigates alone along its own route
    and localizes with sonar fixes like a leader (s; ``localization: both``): out of Kinect view a
    split may go unnoticed, and such a follower would otherwise approach its KPOIs on odometry."""
    off_route_distance: float = 0.5
    """A leader farther than this from its route (m; e.g. carried past its turn by the robot ahead
    before it was promoted) that cannot drive straight to its route point with its body (radius +
    ``stop_margin`` clear of the known map's walls) heads for the last earlier point of its route it
    can drive straight to instead (back to its route, not into the wall), else along the shortest
    path of its body to the route point."""
    sonar_fix: SonarFixConfig = field(default_factory=SonarFixConfig)
    navigator: NavigatorConfig = field(default_factory=NavigatorConfig)

    def __post_init__(self) -> None:
        for name in ("leader_speed", "backoff_speed", "backoff_turn", "search_speed"):
            v = getattr(self, name)
            check(0 < v <= 1, name, f"must be in (0, 1] (a fraction of the robot's limit), got {v}")
        check(-1 <= self.follower_min_speed <= 0, "follower_min_speed",
              f"must be in [-1, 0], got {self.follower_min_speed}")
        positive(self, "patience", "backoff_time", "front_sector_deg", "alone_after")
        check(self.stop_margin >= 0, "stop_margin", f"must be >= 0, got {self.stop_margin}")
        check(self.slow_margin > self.stop_margin, "slow_margin",
              f"must be > stop_margin ({self.stop_margin} m), got {self.slow_margin}")
        check(self.patience_stagger >= 0, "patience_stagger", f"must be >= 0, got {self.patience_stagger}")
        check(self.off_route_distance > 0, "off_route_distance", f"must be > 0, got {self.off_route_distance}")
        check(self.front_sector_deg <= 180, "front_sector_deg", f"must be <= 180, got {self.front_sector_deg}")


def expert_config(scenario: Scenario) -> ExpertConfig:
    """The ``expert`` section of ``scenario`` as a validated :class:`ExpertConfig` (defaults for
    missing keys); a bad value raises ``ConfigError`` naming the scenario file and ``expert.<key>``."""
    return from_mapping(ExpertConfig, scenario.expert, scenario.source, "expert")
