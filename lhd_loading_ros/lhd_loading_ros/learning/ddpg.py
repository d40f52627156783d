"""DDPG (Lillicrap et al. 2015) as the paper trains it: one critic and one actor update per
environment step, soft target updates, Ornstein-Uhlenbeck exploration noise scaled by a
factor that decays linearly.

Everything numeric comes from :class:`DdpgConfig`, built from config/lhd_params.yaml
(``paper.ddpg`` for the paper's table, ``training`` for what the paper leaves open).
Time-limit truncation is not terminal: the replay stores ``not_terminal`` = 1 - terminated,
so a truncated transition still bootstraps from Q'(o', mu'(o')).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch

from lhd_loading_ros.task.observation import OBS_DIM
from lhd_loading_ros.task.actions import ACT_DIM
from lhd_loading_ros.learning.mlp import FlatAdam, FlatMlp


@dataclass(frozen=True)
class DdpgConfig:
    actor_lr: float
    critic_lr: float
    gamma: float
    replay_size: int
    batch_size: int
    tau: float
    ou_mu: float
    ou_sigma: float
    ou_theta: float
    ou_dt: float
    total_steps: int
    noise_decay_steps: int
    noise_final_scale: float
    learning_starts: int
    hidden_sizes: tuple
    reward_scale: float
    eval_every: int
    eval_episodes: int
    eval_seed: int
    checkpoint_every: int
    twin_critics: int = 0          # 1: clipped double Q (two critics, the target's min; Fujimoto et al. 2018)
    lr_final_scale: float = 1.0    # both learning rates fall linearly to this share of theirs ...
    lr_decay_from: int = 0         # ... from this step to total_steps (1.0: constant, the paper)
    demo_bc: float = 0.0           # > 0: weight of the actor's Q-filtered behaviour cloning on demonstrations (DDPGfD)
    critic_huber: float = 0.0      # > 0: the critics' loss is Huber with this delta (scaled returns), else squared
    noise_after_decay: float = 0.0  # > 0: the noise factor from noise_decay_steps on, in place of noise_final_scale
    demo_bc_return_filter: int = 0  # 1: clone a demonstration's row where its own return G beats Q(o, mu(o))
    actor_preact_l2: float = 0.0   # > 0: the actor's loss gains this weight times mean_i ||z_i||^2, z tanh's input
    demo_q_lower_bound: int = 0    # 1: a demonstration's row regresses on max(TD target, its own return G)

    @classmethod
    def from_config(cls, cfg: dict) -> "DdpgConfig":
        d, t = cfg["paper"]["ddpg"], cfg["training"]
        return cls(
            actor_lr=d["actor_lr"], critic_lr=d["critic_lr"], gamma=d["gamma"], replay_size=d["replay_size"],
            batch_size=d["batch_size"], tau=d["tau"], ou_mu=d["ou_mu"], ou_sigma=d["ou_sigma"],
            ou_theta=d["ou_theta"], ou_dt=d["ou_dt"], total_steps=t["total_steps"],
            noise_decay_steps=t["noise_decay_steps"], noise_final_scale=t["noise_final_scale"],
            learning_starts=t["learning_starts"], hidden_sizes=tuple(t["hidden_sizes"]),
            reward_scale=t["reward_scale"], eval_every=t["eval_every"], eval_episodes=t["eval_episodes"],
            eval_seed=t["eval_seed"], checkpoint_every=t["checkpoint_every"],
            twin_critics=int(t.get("twin_critics", 0)),
            lr_final_scale=float(t.get("lr_final_scale", 1.0)), lr_decay_from=int(t.get("lr_decay_from", 0)),
            demo_bc=float(t.get("demo_bc", 0.0)), critic_huber=float(t.get("critic_huber", 0.0)),
            noise_after_decay=float(t.get("noise_after_decay", 0.0)),
            demo_bc_return_filter=int(t.get("demo_bc_return_filter", 0)),
            actor_preact_l2=float(t.get("actor_preact_l2", 0.0)),
            demo_q_lower_bound=int(t.get("demo_q_lower_bound", 0)),
        )

    def to_dict(self) -> dict:
        d = asdict(self)
        d["hidden_sizes"] = list(self.hidden_sizes)
        return d


# ---------------------------------------------------------------------- exploration
class OUNoise:
    """Ornstein-Uhlenbeck process, Euler-Maruyama:
    x <- x + theta (mu - x) dt + sigma sqrt(dt) N(0, 1)."""

    def __init__(self, dim: int, mu: float, sigma: float, theta: float, dt: float, rng: np.random.Generator):
        self.dim, self.mu, self.sigma, self.theta, self.dt = dim, mu, sigma, theta, dt
        self.rng = rng
        self.x = np.full(dim, mu, dtype=np.float64)

    def reset(self) -> None:
        self.x[:] = self.mu

    def sample(self) -> np.ndarray:
        self.x += self.theta * (self.mu - self.x) * self.dt + self.sigma * np.sqrt(self.dt) * self.rng.standard_normal(self.dim)
        return self.x.copy()


def noise_scale(step: int, decay_steps: int, final: float, after: float = 0.0) -> float:
    """Linear decay from 1 at step 0 to `final` at `decay_steps`, then constant: `final`, or
    `after` when it is > 0 (training.noise_after_decay)."""
    if decay_steps <= 0:
        return after if after > 0.0 else final
    if after > 0.0 and step >= decay_steps:
        return after
    f = min(1.0, max(0.0, step / decay_steps))
    return 1.0 + (final - 1.0) * f


def lr_scale(step: int, start: int, total: int, final: float) -> float:
    """Share of the learning rates at `step` (training.lr_final_scale / lr_decay_from): 1 up to
    `start`, then linear to `final` at `total`, `final` after it."""
    if final >= 1.0 or step <= start:
        return 1.0
    if step >= total or total <= start:
        return final
    return 1.0 + (final - 1.0) * (step - start) / (total - start)


# ---------------------------------------------------------------------- replay
class ReplayBuffer:
    """Ring buffer of transitions in one float32 tensor per row:
    [o (12) | a (3) | r | not_terminal | o' (12)], sampled uniformly with replacement.
    aux=True adds a last column, a reward term stored apart (the tilt penalty under a training
    schedule, TiltRamp): a sample's reward is then r + aux_weight * aux, with the weight of the
    moment, so every transition in the buffer is relabelled when the weight changes.
    demo=True adds a last column (after aux), 1 for a scripted demonstration's transition
    (training.demo_bc); sample() then returns that column as a fifth tensor.
    demo_return=True (training.demo_bc_return_filter) adds, before the flag, the demonstration's
    own discounted return from the row on, G = sum_k gamma^k r_{t+k} to its episode's end (and
    with aux a second column, the same sum of the aux term), written by set_demo_return once the
    demonstration has ended; until then (and for every other row) G = -inf. sample() then returns
    G (+ aux_weight G_aux) as a sixth tensor."""

    def __init__(self, capacity: int, obs_dim: int = OBS_DIM, act_dim: int = ACT_DIM, aux: bool = False,
                 demo: bool = False, demo_return: bool = False):
        if capacity < 1:
            raise ValueError(f"replay capacity must be >= 1, got {capacity}")
        if demo_return and not demo:
            raise ValueError("a demonstration's return column needs the demonstration flag (ReplayBuffer(demo=True))")
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.aux = bool(aux)
        self.demo = bool(demo)
        self.demo_return = bool(demo_return)
        base = 2 * obs_dim + act_dim + 2
        self._aux_col = base if self.aux else None
        # G (and G_aux with aux) between the aux column and the flag, which stays last
        self._g_col = base + int(self.aux) if self.demo_return else None
        self.width = base + int(self.aux) + (1 + int(self.aux)) * int(self.demo_return) + int(self.demo)
        self.added = 0                    # rows ever added: set_demo_return's check that a row is still there
        self.data = torch.zeros(capacity, self.width, dtype=torch.float32)
        self._np = self.data.numpy()      # shares memory: writes without torch overhead
        self.capacity = capacity
        self.size = 0
        self.pos = 0
        self.aux_weight = 0.0

    def add(self, o, a, r: float, terminated: bool, o2, aux: float = 0.0, demo: bool = False) -> int:
        """Store one transition; returns its ticket (the count of rows added before it), which
        set_demo_return takes."""
        row = self._np[self.pos]
        k = self.obs_dim
        row[:k] = o
        row[k:k + self.act_dim] = a
        k += self.act_dim
        row[k] = r
        row[k + 1] = 0.0 if terminated else 1.0
        row[k + 2:k + 2 + self.obs_dim] = o2
        if self.aux:
            row[self._aux_col] = aux
        elif aux != 0.0:
            raise ValueError("this replay buffer stores no aux reward term (ReplayBuffer(aux=True))")
        if self.demo:
            row[-1] = 1.0 if demo else 0.0
        elif demo:
            raise ValueError("this replay buffer stores no demonstration flag (ReplayBuffer(demo=True))")
        if self.demo_return:            # unknown until the demonstration ends (never, for the actor's rows)
            row[self._g_col] = -np.inf
            if self.aux:
                row[self._g_col + 1] = 0.0
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        self.added += 1
        return self.added - 1

    def set_demo_return(self, rows: list, gamma: float) -> int:
        """A finished demonstration's rows, as (ticket, r, aux) in the order they were added (ticket:
        what add returned): write each row's G = r_t + gamma G_{t+1} (G after the last row 0: the
        realised return to the episode's end, without a bootstrap where the time limit cut it) and
        the same sum of aux. Rows overwritten since (the ring went round) are skipped. Returns the
        number written."""
        if not self.demo_return:
            raise ValueError("this replay buffer stores no demonstration returns (ReplayBuffer(demo_return=True))")
        g = g_aux = 0.0
        written = 0
        for ticket, r, aux in reversed(rows):
            g = float(r) + gamma * g
            g_aux = float(aux) + gamma * g_aux
            if self.added - ticket > self.capacity:
                continue
            row = self._np[ticket % self.capacity]
            row[self._g_col] = g
            if self.aux:
                row[self._g_col + 1] = g_aux
            written += 1
        return written

    def sample(self, batch: int, generator: torch.Generator):
        idx = torch.randint(self.size, (batch,), generator=generator)
        b = self.data.index_select(0, idx)
        k = self.obs_dim + self.act_dim
        r = b[:, k:k + 1]
        if self.aux and self.aux_weight != 0.0:
            r = r + self.aux_weight * b[:, self._aux_col:self._aux_col + 1]
        if self.demo_return:     # ..., the flag, the demonstration's return from the row (G + w G_aux)
            g = b[:, self._g_col:self._g_col + 1]
            if self.aux and self.aux_weight != 0.0:
                g = g + self.aux_weight * b[:, self._g_col + 1:self._g_col + 2]
            return b[:, :k], r, b[:, k + 1:k + 2], b[:, k + 2:k + 2 + self.obs_dim], b[:, -1:], g
        if self.demo:      # (o|a), r, not_terminal, o', demonstration flag
            return b[:, :k], r, b[:, k + 1:k + 2], b[:, k + 2:k + 2 + self.obs_dim], b[:, -1:]
        return b[:, :k], r, b[:, k + 1:k + 2], b[:, k + 2:k + 2 + self.obs_dim]   # (o|a), r, not_terminal, o'

    def state_dict(self) -> dict:
        return {"data": self.data[: self.size].clone(), "pos": self.pos, "size": self.size,
                "aux": self.aux, "demo": self.demo, "demo_return": self.demo_return, "added": self.added}

    def load_state_dict(self, d: dict) -> None:
        n = int(d["size"])
        # which extra columns the checkpoint's rows hold: named in the checkpoint since 2026-11-27. The
        # widths alone cannot tell an aux column from a flag column (the same width), so both are
        # named; before that, one extra column was the tilt ramp's aux term (the flag did not exist)
        # and two were aux and flag (the first checkpoints with the flag)
        base = 2 * self.obs_dim + self.act_dim + 2
        extra = d["data"].shape[1] - base
        theirs = (bool(d.get("aux", extra >= 1)), bool(d.get("demo", extra == 2)))
        mine = (self.aux, self.demo)
        if theirs == mine and bool(d.get("demo_return", False)) != self.demo_return:
            raise ValueError(f"the replay checkpoint {'holds' if d.get('demo_return') else 'does not hold'} the demonstrations' "
                             f"returns, this run's replay {'does' if self.demo_return else 'does not'} "
                             "(training.demo_bc_return_filter): resume it with the same setting, or use another --out")
        if theirs != mine:
            what = {(True, False): "the tilt term apart (task.r_tilt_ramp_after_success > 0)",
                    (False, True): "the demonstration flag (training.demo_bc > 0)",
                    (True, True): "the tilt term apart and the demonstration flag",
                    (False, False): "neither the tilt term apart nor the demonstration flag"}
            raise ValueError(f"the replay checkpoint holds {what[theirs]}, this run's replay {what[mine]}: resume it "
                             "with the same task.r_tilt_ramp_* and training.demo_bc settings, or use another --out")
        if d["data"].shape[1] != self.width or n > self.capacity:
            raise ValueError(f"replay checkpoint does not match this buffer's layout or capacity ({d['data'].shape[1]} "
                             f"columns, {n:,} rows; this buffer: {self.width} columns, capacity {self.capacity:,}): "
                             "resume it with the same paper.ddpg.replay_size")
        self.data[:n].copy_(d["data"])
        self.size, self.pos = n, int(d["pos"])
        # (a checkpoint before the count: the smallest count that maps to the same ring position)
        self.added = int(d.get("added", n if n < self.capacity else self.capacity + self.pos))


class TiltRamp:
    """The tilt penalty's training schedule (task.r_tilt_ramp_after_success R,
    r_tilt_ramp_steps S): weight 0 until a periodic evaluation of the noise-free actor succeeds
    in at least a fraction R of its episodes, then rising linearly to 1 over S steps (S = 0: at
    once). Why: with the whole penalty from the first step, 2 of 9 RLD seeds never found loading
    (docs/training.md "Tilt penalty"); the evaluation, not a training episode, says the actor
    has found it (a random actor's episode meets the success test now and then). R = 0: off,
    the weight is 1 throughout. pitch_margin (task.r_tilt_ramp_pitch_margin): r_success's margins
    (task.r_success_pitch_margin_deg and task.r_success_mass_margin_kg) ride on the same schedule
    (until the ramp, r_success is paid at the paper's 40 deg and 20 kg; the replay's aux column then
    also holds what the margins take away from it)."""

    def __init__(self, after_success: float, steps: int, pitch_margin: bool = False):
        if not (0.0 <= after_success <= 1.0) or steps < 0:
            raise ValueError(f"tilt ramp: after_success {after_success} must be in [0, 1] and steps {steps} >= 0")
        self.after_success, self.steps = float(after_success), int(steps)
        self.pitch_margin = bool(pitch_margin)
        self.start_step: int | None = None

    @property
    def enabled(self) -> bool:
        return self.after_success > 0.0

    def evaluated(self, success_rate: float, step: int) -> bool:
        """A periodic evaluation's success rate at `step`; True when it starts the ramp."""
        if not self.enabled or self.start_step is not None or success_rate < self.after_success:
            return False
        self.start_step = int(step)
        return True

    def weight(self, step: int) -> float:
        if not self.enabled:
            return 1.0
        if self.start_step is None:
            return 0.0
        if self.steps == 0:
            return 1.0
        return min(1.0, max(0.0, (step - self.start_step) / self.steps))

    def state_dict(self) -> dict:
        d = {"after_success": self.after_success, "steps": self.steps, "start_step": self.start_step}
        return {**d, "pitch_margin": True} if self.pitch_margin else d   # (states before the key: no margin)

    def load_state_dict(self, d: dict) -> None:
        theirs = (float(d["after_success"]), int(d["steps"]), bool(d.get("pitch_margin", False)))
        if theirs != (self.after_success, self.steps, self.pitch_margin):
            raise ValueError(f"the checkpoint's tilt ramp (after an evaluation with success >= {d['after_success']}, "
                             f"over {d['steps']} steps, success margins ramped: {theirs[2]}) is not this config's "
                             f"({self.after_success}, {self.steps}, {self.pitch_margin}): "
                             "resume with the same task.r_tilt_ramp_* settings or use another --out")
        self.start_step = None if d["start_step"] is None else int(d["start_step"])


# ---------------------------------------------------------------------- agent
class DdpgAgent:
    def __init__(self, cfg: DdpgConfig, seed: int, obs_dim: int = OBS_DIM, act_dim: int = ACT_DIM):
        self.cfg = cfg
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.gen = torch.Generator().manual_seed(int(seed))
        h = list(cfg.hidden_sizes)
        self.actor = FlatMlp([obs_dim, *h, act_dim], "tanh", generator=self.gen)
        self.critic = FlatMlp([obs_dim + act_dim, *h, 1], "identity", generator=self.gen)
        self.actor_t = FlatMlp(self.actor.sizes, "tanh")
        self.critic_t = FlatMlp(self.critic.sizes, "identity")
        self.actor_t.copy_from(self.actor)
        self.critic_t.copy_from(self.critic)
        self.actor_opt = FlatAdam(self.actor, cfg.actor_lr)
        self.critic_opt = FlatAdam(self.critic, cfg.critic_lr)
        # clipped double Q (training.twin_critics): a second critic, initialised after everything
        # above so that the single-critic agent draws the same weights as before it existed
        self.twin = bool(cfg.twin_critics)
        if self.twin:
            self.critic2 = FlatMlp(self.critic.sizes, "identity", generator=self.gen)
            self.critic2_t = FlatMlp(self.critic.sizes, "identity")
            self.critic2_t.copy_from(self.critic2)
            self.critic2_opt = FlatAdam(self.critic2, cfg.critic_lr)
        self.updates = 0
        # behaviour cloning (cfg.demo_bc): demonstration rows sampled, and those the Q-filter let through
        self.bc_rows, self.bc_passed = 0, 0
        # the actor's tanh input over the last batch (kept with cfg.actor_preact_l2; preact_sq reduces it when asked)
        self._last_preact: torch.Tensor | None = None

    @property
    def preact_sq(self) -> float:
        """mean ||z||^2 of the actor's tanh input over the last batch (nan unless cfg.actor_preact_l2 > 0): reduced
        here, when the training logs it, not in every update."""
        z = self._last_preact
        return float("nan") if z is None else float((z * z).sum(1).mean())

    def set_lr_scale(self, scale: float) -> None:
        """Both optimisers' learning rates at `scale` times the configured ones."""
        self.actor_opt.lr = self.cfg.actor_lr * scale
        self.critic_opt.lr = self.cfg.critic_lr * scale
        if self.twin:
            self.critic2_opt.lr = self.cfg.critic_lr * scale

    def _td_grad(self, err: torch.Tensor) -> torch.Tensor:
        """d/dQ of the critic's loss per row, over 2 / B: the TD error, clipped to +-critic_huber."""
        d = self.cfg.critic_huber
        return err.clamp(-d, d) if d > 0.0 else err

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action mu(o) in [-1, 1]^3 (float64)."""
        with torch.no_grad():
            x = torch.from_numpy(np.asarray(obs, dtype=np.float32).reshape(1, -1))
            return self.actor(x)[0].double().numpy()

    def actor_numpy(self):
        """A snapshot of the actor as the exported NumpyActor (what the policy node runs)."""
        from lhd_loading_ros.policy.actor_file import NumpyActor
        return NumpyActor(self.actor.numpy_weights())

    def update(self, oa: torch.Tensor, r: torch.Tensor, not_term: torch.Tensor, o2: torch.Tensor,
               demo: torch.Tensor | None = None, demo_return: torch.Tensor | None = None) -> tuple[float, float]:
        """One critic step on the TD target and one actor step on -Q(o, mu(o)); then the
        soft target updates. Returns the TD errors and Q(o, mu(o)) of the batch (tensors).
        With twin critics the target is the smaller of the two target critics' values (the
        overestimation that made seeds collapse late feeds on the max), both critics learn
        it, and the actor follows the first (clipped double Q, without TD3's delayed actor
        and target smoothing).
        demo (B x 1, 1 for a demonstration's transition) with cfg.demo_bc = w > 0: the actor's
        loss gains w / B * sum_i f_i ||mu(o_i) - a_i||^2 over the batch's demonstration rows
        whose action the updated critic values above the actor's, f_i = 1[Q(o_i, a_i) >
        Q(o_i, mu(o_i))] (the Q-filter of DDPGfD, Nair et al. 2018): the actor is pulled to the
        teacher only where the critic says the teacher does better.
        demo_return (B x 1, cfg.demo_bc_return_filter = 1): the demonstration's own discounted return
        from the row (unscaled; -inf while unknown) in place of Q(o_i, a_i) in that test, f_i =
        1[reward_scale G_i > Q(o_i, mu(o_i))] (the test of self-imitation learning, Oh et al. 2018):
        what the teacher went on to earn, which a critic that values the actor's own continuation
        cannot see.
        cfg.demo_q_lower_bound = 1 (with demo_return): the critics' target on a demonstration's row is max(y,
        reward_scale G_i), so the teacher's continuation, which the one-step target (the actor's own) never values,
        reaches the critic.
        cfg.actor_preact_l2 = w > 0: the actor's loss also gains w / B * sum_i ||z_i||^2, z_i the input of the actor's
        output tanh (the pre-activation penalty of rlkit's DDPG and SAC, policy_pre_activation_weight), whose gradient
        2 w z / B is added at z: without it the outputs saturate (|z| of 5-90 measured, tanh' < 2e-4) and neither
        the critic's gradient nor the cloning term can move an action that sits at +-1."""
        cfg = self.cfg
        B = oa.shape[0]
        # TD target y = s r + gamma (1 - terminated) Q'(o', mu'(o'))
        a2 = self.actor_t(o2)
        o2a2 = torch.cat((o2, a2), 1)
        q2 = self.critic_t(o2a2)
        if self.twin:
            q2 = torch.minimum(q2, self.critic2_t(o2a2))
        y = torch.addcmul(r * cfg.reward_scale, not_term, q2, value=cfg.gamma)
        if cfg.demo_q_lower_bound and demo_return is not None:
            # what the demonstration went on to earn from the row is a return Q*(o, a) is at least: the critic
            # regresses on it where it exceeds the one-step target (the value loss of self-imitation learning,
            # Oh et al. 2018; optimality tightening, He et al. 2017). Rows without one hold -inf
            y = torch.maximum(y, demo_return * cfg.reward_scale)
        # critic: L = mean (Q(o, a) - y)^2, or with cfg.critic_huber = d > 0 the Huber loss
        # L = mean 2 h_d(Q - y), h_d(e) = e^2 / 2 for |e| <= d, d (|e| - d / 2) beyond (twice
        # torch's huber_loss, so that it is the squared loss inside d): its gradient is the TD
        # error clipped to [-d, d], as DQN clips it
        q, cache = self.critic.forward(oa)
        err = q - y
        self.critic.backward(cache, self._td_grad(err) * (2.0 / B))
        self.critic_opt.step()
        if self.twin:
            qb, cache_b = self.critic2.forward(oa)
            self.critic2.backward(cache_b, self._td_grad(qb - y) * (2.0 / B))
            self.critic2_opt.step()
        # actor: maximise Q(o, mu(o)) through the updated critic (as CleanRL / Lillicrap)
        o = oa[:, : self.obs_dim]
        pi, acache = self.actor.forward(o)
        qpi, ccache = self.critic.forward(torch.cat((o, pi), 1))
        dq = torch.full_like(qpi, -1.0 / B)
        dx = self.critic.backward(ccache, dq, weight_grads=False, input_grad=True)
        da = dx[:, self.obs_dim:]
        if demo is not None and cfg.demo_bc > 0.0:
            if demo_return is not None:
                passed = demo * (demo_return * cfg.reward_scale > qpi)     # the teacher's own return
            else:
                with torch.no_grad():
                    q_demo = self.critic(oa)             # Q(o, a) of the stored action, by the updated critic
                passed = demo * (q_demo > qpi)
            # d/dmu of w/B sum f ||mu - a||^2 = 2 w f (mu - a) / B
            da = da + (2.0 * cfg.demo_bc / B) * passed * (pi - oa[:, self.obs_dim:])
            self.bc_rows += int(demo.sum())
            self.bc_passed += int(passed.sum())
        dz = None
        if cfg.actor_preact_l2 > 0.0:
            # d/dz of w/B sum_i ||z_i||^2 = 2 w z / B, on tanh's input: a saturated output (|z| >> 1) passes
            # almost none of the critic's or the cloning's gradient (tanh'(z) = 1 - tanh(z)^2, 1.8e-4 at 5),
            # so an actor at +-1 cannot be moved off it; the penalty keeps z where tanh still passes them
            z = self.actor.out_preactivation(acache)
            dz = z * (2.0 * cfg.actor_preact_l2 / B)
            self._last_preact = z
        self.actor.backward(acache, da, dz_out=dz)
        self.actor_opt.step()
        self.actor_t.soft_update_from(self.actor, cfg.tau)
        self.critic_t.soft_update_from(self.critic, cfg.tau)
        if self.twin:
            self.critic2_t.soft_update_from(self.critic2, cfg.tau)
        self.updates += 1
        return err, qpi

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        d = {
            "actor": self.actor.flat.clone(), "critic": self.critic.flat.clone(),
            "actor_t": self.actor_t.flat.clone(), "critic_t": self.critic_t.flat.clone(),
            "actor_opt": self.actor_opt.state_dict(), "critic_opt": self.critic_opt.state_dict(),
            "updates": self.updates, "gen": self.gen.get_state(),
        }
        if self.twin:
            d.update(critic2=self.critic2.flat.clone(), critic2_t=self.critic2_t.flat.clone(),
                     critic2_opt=self.critic2_opt.state_dict())
        return d

    def load_state_dict(self, d: dict) -> None:
        if ("critic2" in d) != self.twin:
            raise ValueError(f"the checkpoint has {'two critics' if 'critic2' in d else 'one critic'}, this agent "
                             f"{'two' if self.twin else 'one'}: resume with the same training.twin_critics "
                             "or use another --out")
        for name in ("actor", "critic", "actor_t", "critic_t") + (("critic2", "critic2_t") if self.twin else ()):
            net = getattr(self, name)
            if d[name].shape != net.flat.shape:
                raise ValueError(f"checkpoint's {name} has {d[name].numel()} parameters, this agent "
                                 f"{net.n_params} (hidden sizes differ?)")
            net.flat.copy_(d[name])
        self.actor_opt.load_state_dict(d["actor_opt"])
        self.critic_opt.load_state_dict(d["critic_opt"])
        if self.twin:
            self.critic2_opt.load_state_dict(d["critic2_opt"])
        self.updates = int(d["updates"])
        self.gen.set_state(d["gen"])
