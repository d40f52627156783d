"""Scripted demonstrations in the replay (training.demo_share; not in the paper's DDPG).

Every RLD actor trained on the paper's reward drives at full wheel speed while it lifts, and on
15 deg piles the tip leaves the face with 21-23 kg. The scripted maneuver of the simulator
(lhd_sim_node.scripted: drive in, curl the bucket to `pre_curl`, then lift and curl at full rate
from the pile's x_min or the first wheel drift, the wheels at a share `crowd` of full speed) loads
33-41 kg on the same piles, at a higher return under the training reward, a maneuver that the
actor's exploration (OU noise around a saturated wheel command) hardly ever tries. With
demo_share > 0 that share of the training episodes, up to training.demo_until_step (0: up to
noise_decay_steps, where the exploration noise reaches its floor), is driven by the
scripted maneuver, each with its own crowd drawn from [demo_crowd_min, demo_crowd_max]; its
transitions go into the one replay like the actor's (DDPG is off-policy), so the critic sees what
the slower, longer crowd is worth and the actor may learn it (Vecerik et al. 2017 keep
demonstrations in the replay in the same way). The demonstration reads the simulator's state
(the tip's x, the pile's x_min, the drift flags), which the actor never sees: it is a teacher in
training only, and no actor depends on it at run time.

Which episodes are demonstrations and their crowd follow from the episode's seed alone (a stream
of its own), so a run without demonstrations draws exactly what it drew before, and a resumed run
the same as an uninterrupted one. With training.demo_told_high = d > 0 every episode whose slope is
told at least d deg too steep (known once the environment has drawn its conditions) is one as well,
its crowd from a second stream of the same seed (`told_high_crowd`): the case every trained actor
fails most, where the teacher's late lift loads what the actors' early one loses (docs/training.md
"How much a slope told too high can give").

With training.demo_told_zones = 1 the demonstration reads the zones the actor is told (env.zones:
with a slope-estimate error, those the end-zone node builds from the estimate) instead of the
pile's own, and with training.demo_end_zone_stop > 0 it stops the wheels while it lifts below the
end zone's z_min within that distance of its x_max (lhd_sim_node.scripted). The teacher then knows
no more of the pile than the actor does (the tip, the drift flags and the told zones, which the
observation's alpha and d_end carry) and still loads piles shallower than it is told: 4 of 4
attempts in every cell of a 15 deg pile told 0..+15 deg too steep, where the pile's-own-zones
teacher loads none at +10 and +15 (docs/training.md "A teacher that knows what the actor knows").

With training.demo_where_teacher_wins = 1 (and the slope curriculum on) an episode that any of the above makes a
demonstration stays one only where the teacher's recent success rate on the pile's slope bin (the curriculum's own
test, over its window of demonstrations) is at least the actor's: in both of the thirty-fourth session's RLC runs the
teacher earned r_success on 0.82-0.89 of its 10-12.5 deg piles against the actor's 0.00-0.15, and on 0.05-0.07 of its
30-40 deg piles against the actor's 0.16-0.29 (docs/training.md "A slope the LiDAR mostly gets right").

With training.demo_failing_share = s > 0 (and the slope curriculum on) an episode the actor would drive
is a demonstration as well with probability s x f, f the failure rate the curriculum holds for the
pile's slope bin (its recent actor episodes, by the curriculum's own test), drawn from a third stream
of the episode's seed (`failing_crowd`): the teacher is sent where the actor still fails. On the 10-40
deg RLC file the teacher earns r_success in 76-89 % of its 10-15 deg piles and the actors in 8-39 %,
while on 20-40 deg piles the actors win (86-88 % against 33-38 %), so a flat demo_share spends most of
its demonstrations where the teacher is worse (docs/training.md "Demonstrations where the actor fails").
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

DEMO_STREAM = 0xDE


@dataclass(frozen=True)
class DemoConfig:
    share: float          # share of training episodes driven by the scripted maneuver
    crowd_min: float      # wheel speed while lifting, share of full speed, drawn per episode
    crowd_max: float
    pre_curl: float       # rad: bucket curl before the lift
    until_step: int       # no demonstration starts at or after this step (demo_until_step, 0: noise_decay_steps)
    told_zones: bool = False      # read the told zones (env.zones), not the pile's own (demo_told_zones)
    end_zone_stop: float = 0.0    # m: wheels stop while lifting below z_min within this of x_max (0: off)
    push_curl: float = 0.0        # rad: curl while pushing (demo_push_curl; maneuver.push_curl_action)
    late_lift: float = 0.0        # share of the end zone where an unstalled push lifts (demo_late_lift)
    told_high: float = 0.0        # deg: every episode told at least this much too steep is a demonstration (0: off)
    drift_confirm: int = 1        # decisions a drift flag the actor sees must hold before the lift (demo_drift_confirm; 1: off)
    failing: float = 0.0          # an actor's episode on a slope bin failing at rate f is a demonstration with probability
                                  # failing x f (demo_failing_share; needs the slope curriculum; 0: off)
    where_teacher_wins: bool = False   # a demonstration only on a slope bin where the teacher's recent success rate is
                                       # at least the actor's (demo_where_teacher_wins; needs the slope curriculum)

    @classmethod
    def from_training(cls, t: dict) -> "DemoConfig | None":
        share = float(t.get("demo_share", 0.0))
        if share <= 0.0:
            return None
        lo, hi = float(t.get("demo_crowd_min", 0.5)), float(t.get("demo_crowd_max", 0.75))
        if not (0.0 < lo <= hi <= 1.0):
            raise ValueError(f"training.demo_crowd_min / demo_crowd_max = {lo:g} / {hi:g}: expected "
                             "0 < demo_crowd_min <= demo_crowd_max <= 1 (shares of full wheel speed)")
        until = int(t.get("demo_until_step", 0)) or int(t["noise_decay_steps"])
        stop = float(t.get("demo_end_zone_stop", 0.0))
        if not (0.0 <= stop <= 1.0):
            raise ValueError(f"training.demo_end_zone_stop = {stop:g}: expected 0 (off) to 1 m")
        from lhd_loading_ros.policy.teacher import TeacherSetting
        ts = TeacherSetting.from_config({"training": {**t, "demo_crowd_min": lo, "demo_crowd_max": hi,
                                                      "demo_pre_curl": t.get("demo_pre_curl", 0.3)}})
        told_high = float(t.get("demo_told_high", 0.0))
        if not (0.0 <= told_high <= 45.0):      # NaN fails too
            raise ValueError(f"training.demo_told_high = {told_high!r}: expected a slope error in [0, 45] deg (0: off)")
        confirm = t.get("demo_drift_confirm", 1)
        if isinstance(confirm, bool) or int(confirm) != confirm or not 1 <= int(confirm) <= 50:
            raise ValueError(f"training.demo_drift_confirm = {confirm!r}: expected a whole number of decisions in "
                             "[1, 50] (1: every drift flag the simulator's teacher reads lifts at once)")
        failing = float(t.get("demo_failing_share", 0.0))
        if not (0.0 <= failing <= 0.9):         # NaN fails too; at 1 a bin that always fails (or has had no actor
            # episode yet: its rate is 1) would be all demonstrations, and the actor never measured there again
            raise ValueError(f"training.demo_failing_share = {failing!r}: expected a probability in [0, 0.9] (0: off; "
                             "at 1 a bin failing every attempt would never see the actor again)")
        wins = t.get("demo_where_teacher_wins", 0)
        if isinstance(wins, bool) or wins not in (0, 1):
            raise ValueError(f"training.demo_where_teacher_wins = {wins!r}: expected 0 (off) or 1 (a demonstration only on "
                             "the slope bins where the teacher's recent success rate is at least the actor's)")
        return cls(share, lo, hi, float(t.get("demo_pre_curl", 0.3)), until,
                   bool(int(t.get("demo_told_zones", 0))), stop, ts.push_curl, ts.late_lift, told_high, int(confirm),
                   failing, bool(wins))

    def to_dict(self) -> dict:
        """The settings (run.json); `failing` only when on, so that runs written before it read the same."""
        d = asdict(self)
        if not self.failing:
            d.pop("failing")
        if not self.where_teacher_wins:
            d.pop("where_teacher_wins")
        return d

    def draw(self, seed_k: int, step: int) -> float | None:
        """The crowd of the demonstration that episode `seed_k` (starting at `step`) is, or None
        when the actor drives it."""
        if step >= self.until_step:
            return None
        rng = np.random.default_rng([int(seed_k), DEMO_STREAM])
        if rng.random() >= self.share:
            return None
        return float(rng.uniform(self.crowd_min, self.crowd_max))

    def told_high_crowd(self, seed_k: int, step: int, told_error_deg: float) -> float | None:
        """The crowd of the demonstration that episode `seed_k` (starting at `step`, its slope told
        `told_error_deg` too steep: the told slope minus the pile's) is because it is told too steep
        (demo_told_high), or None: off, past until_step, or told less than demo_told_high too steep."""
        if self.told_high <= 0.0 or step >= self.until_step or not told_error_deg >= self.told_high:
            return None
        rng = np.random.default_rng([int(seed_k), DEMO_STREAM, 1])
        return float(rng.uniform(self.crowd_min, self.crowd_max))

    def failing_crowd(self, seed_k: int, step: int, failure_rate: float) -> float | None:
        """The crowd of the demonstration that episode `seed_k` (starting at `step`, on a pile whose slope
        bin the slope curriculum counts failing at `failure_rate` over its recent actor episodes) is because
        its bin fails (demo_failing_share), or None: off, past until_step, or not drawn. One draw u from a
        third stream of the episode's seed: a demonstration when u < failing x failure_rate, so a bin that
        always fails gets `failing`, one that never fails none."""
        if self.failing <= 0.0 or step >= self.until_step or not 0.0 <= failure_rate <= 1.0:
            return None
        rng = np.random.default_rng([int(seed_k), DEMO_STREAM, 2])
        if rng.random() >= self.failing * failure_rate:
            return None
        return float(rng.uniform(self.crowd_min, self.crowd_max))

    def failing_crowd_on(self, curriculum, seed_k: int, step: int, alpha_deg: float) -> float | None:
        """failing_crowd at the failure rate `curriculum` (a learning.curriculum.SlopeCurriculum) holds now
        for the bin of the pile's slope `alpha_deg` (held to the curriculum's range)."""
        if self.failing <= 0.0:
            return None
        alpha = min(curriculum.hi, max(curriculum.lo, float(alpha_deg)))
        return self.failing_crowd(seed_k, step, float(curriculum.failure_rates()[curriculum.bin_of(alpha)]))

    def action(self, env, crowd: float) -> np.ndarray:
        return demo_action(env, crowd, self.pre_curl, self.told_zones, self.end_zone_stop,
                           push_curl=self.push_curl, late_lift=self.late_lift, drift_confirm=self.drift_confirm)


def demo_action(env, crowd: float, pre_curl: float, told_zones: bool = False,
                end_zone_stop: float = 0.0, push_curl: float = 0.0, late_lift: float = 0.0,
                measured: bool = False, drift_confirm: int = 1) -> np.ndarray:
    """The scripted maneuver's normalised action for env's current state: arm still and wheels
    full until the tip passes x_min (the pile's own, or with told_zones the told one) or a wheel
    drifts, then curl to pre_curl and lift and curl at full rate with the wheels at `crowd` of full
    speed; with end_zone_stop > 0 the wheels stop while the tip is below z_min within that distance
    of x_max (of the same zones). measured: from the state the machine's sensors give (env.measured_state,
    the arm's angle-sensor offsets in it), as the teacher runs on the machine (lhd experiment paper); the
    training's demonstrations read the true state (the simulator's teacher, an oracle like the pile's zones).
    push_curl / late_lift: the push-curl maneuver (policy/maneuver.push_curl_action), whose memory of the
    attempt lives on env (`_teacher_memory`) and is emptied at each episode's first step.
    drift_confirm > 1 (`training.demo_drift_confirm`): the teacher reads the drift flags the actor observes
    (env.measured_state: the bridge's window where the episode lags it, randomization.drift_flag_lag_max_s) and
    lifts on one only once it has been up for drift_confirm steps in a row (policy/teacher.confirm_drift, as
    the machine's teacher does with teacher_drift_confirm); its count lives on env (`_teacher_drift_run`),
    emptied at each episode's first step, so call this once a step. 1: the flags of the state read, at once."""
    from lhd_loading_ros.policy.teacher import TeacherSetting, confirm_drift, teacher_action

    z = env.zones if told_zones else env.sim.zones
    setting = TeacherSetting(crowd, pre_curl, told_zones, end_zone_stop, push_curl, late_lift)
    memory = None
    if setting.pushes_curled:
        memory = getattr(env, "_teacher_memory", None)
        if memory is None or env.steps == 0:
            memory = env._teacher_memory = {}
    s = env.measured_state if measured else env.state
    if drift_confirm > 1:
        seen = env.measured_state
        run = 0 if env.steps == 0 else getattr(env, "_teacher_drift_run", 0)
        s, env._teacher_drift_run = confirm_drift(
            replace(s, drift=seen.drift, drift_front=seen.drift_front, drift_rear=seen.drift_rear), run, drift_confirm)
    return teacher_action(s, (z.x_min, z.x_max, z.z_min), setting, memory)
