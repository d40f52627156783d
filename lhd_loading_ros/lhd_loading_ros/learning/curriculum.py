"""Slope curriculum for training (training.slope_curriculum; docs/training.md "Slope curriculum").

Every seed of the randomised studies loaded 20-30 deg piles and failed the 15 deg ones: the
shallowest piles need the longest dig for the success test's 20 kg, and with slopes drawn
uniformly over [alpha_min, alpha_max] they are one sixth of the training piles however often they
fail. The curriculum splits the slope range into bins and draws a training pile's slope from them
in proportion to how often the bin's recent training episodes failed, mixed with the uniform draw
so that no slope is left out:

    p_b = u / B + (1 - u) * f_b / sum_k f_k        (uniform when no bin fails)

f_b: the share of the bin's last `window` training episodes that did not succeed (1 for a bin
with none yet), u: the uniform share, B: the bins. Within a bin the slope is uniform. This is
the idea of prioritised level replay (Jiang et al. 2021) with the failure rate as the score. The
evaluations (and everything after training) keep the uniform draw: the curriculum only decides
which piles the learner practises on, not what its figures are measured on.

What counts as a success (training.slope_curriculum_reward_test): 0, the paper's test (SL >= 1:
>= 20 kg and a final pitch > 40 deg); 1, the reward's own test, an attempt that earned r_success
(the paper's test with the training margins, task.r_success_mass_margin_kg and
r_success_pitch_margin_deg). With the margins, an actor that ends a 10 deg pile with 20-23 kg
passes the paper's test, so its bin counts as learned and is drawn no more often, while the
reward still pays it nothing for success there (docs/training.md "The curriculum on the reward's
test").
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CurriculumConfig:
    bins: int = 6
    window: int = 100
    uniform: float = 0.5
    reward_test: int = 0

    @classmethod
    def from_training(cls, t: dict) -> "CurriculumConfig | None":
        """The curriculum of a config's training section, or None when it is off."""
        if not int(t.get("slope_curriculum", 0)):
            return None
        return cls(bins=int(t.get("slope_curriculum_bins", cls.bins)),
                   window=int(t.get("slope_curriculum_window", cls.window)),
                   uniform=float(t.get("slope_curriculum_uniform", cls.uniform)),
                   reward_test=int(t.get("slope_curriculum_reward_test", cls.reward_test)))

    def to_dict(self) -> dict:
        """The settings; reward_test only when on, so that runs written before it resume unchanged."""
        d = {"bins": self.bins, "window": self.window, "uniform": self.uniform}
        return {**d, "reward_test": 1} if self.reward_test else d

    def counts_success(self, paper_success: bool, r_success: float) -> bool:
        """Whether a training attempt counts as a success for the draw: the paper's test, or with
        reward_test also the reward's (r_success, the terminal step's success term, paid)."""
        return bool(paper_success) and (not self.reward_test or r_success > 0.0)


class SlopeCurriculum:
    """Failure-weighted draw of training slopes over [lo_deg, hi_deg] (module docstring)."""

    def __init__(self, lo_deg: float, hi_deg: float, cfg: CurriculumConfig):
        if not hi_deg > lo_deg:
            raise ValueError(f"slope curriculum: the range must be lo < hi, got [{lo_deg}, {hi_deg}] deg")
        if cfg.bins < 1 or cfg.window < 1 or not 0.0 < cfg.uniform <= 1.0:
            # uniform > 0: a bin whose window is all successes must still be drawn, or it is never measured again
            raise ValueError(f"slope curriculum: expected bins >= 1, window >= 1 and 0 < uniform <= 1, got {cfg}")
        self.lo, self.hi, self.cfg = float(lo_deg), float(hi_deg), cfg
        self.edges = np.linspace(self.lo, self.hi, cfg.bins + 1)
        self.recent = [deque(maxlen=cfg.window) for _ in range(cfg.bins)]
        # the demonstrations' own outcomes per bin, by the same test (training.demo_where_teacher_wins): kept only
        # where that key records them, so a run without it saves and resumes what it did before
        self.teacher_recent = [deque(maxlen=cfg.window) for _ in range(cfg.bins)]

    def bin_of(self, slope_deg: float) -> int:
        """The bin holding slope_deg (the top edge belongs to the last bin)."""
        if not self.lo - 1e-9 <= slope_deg <= self.hi + 1e-9:
            raise ValueError(f"slope {slope_deg} deg outside the curriculum's range [{self.lo:g}, {self.hi:g}] deg")
        return int(min(self.cfg.bins - 1, max(0, np.searchsorted(self.edges, slope_deg, side="right") - 1)))

    def record(self, slope_deg: float, success: bool) -> None:
        self.recent[self.bin_of(slope_deg)].append(bool(success))

    def failure_rates(self) -> np.ndarray:
        return np.array([1.0 - float(np.mean(r)) if r else 1.0 for r in self.recent])

    def record_teacher(self, slope_deg: float, success: bool) -> None:
        """A demonstration's outcome (training.demo_where_teacher_wins), by the same test as record()."""
        self.teacher_recent[self.bin_of(slope_deg)].append(bool(success))

    def teacher_wins(self, slope_deg: float) -> bool:
        """Whether the demonstrations' recent success rate in the bin of slope_deg (held to the range) is at least
        the actor's: a bin with no demonstration yet counts as the teacher's (so that it is measured there), a bin
        with no actor episode yet as the actor failing (as failure_rates does)."""
        k = self.bin_of(min(self.hi, max(self.lo, float(slope_deg))))
        t = self.teacher_recent[k]
        if not t:
            return True
        return float(np.mean(t)) >= 1.0 - float(self.failure_rates()[k])

    def probabilities(self) -> np.ndarray:
        b, u = self.cfg.bins, self.cfg.uniform
        f = self.failure_rates()
        if f.sum() <= 0.0:
            return np.full(b, 1.0 / b)
        return u / b + (1.0 - u) * f / f.sum()

    def draw(self, rng: np.random.Generator) -> float:
        """A slope, deg: a bin by probabilities(), then uniform within it."""
        k = int(rng.choice(self.cfg.bins, p=self.probabilities()))
        return float(rng.uniform(self.edges[k], self.edges[k + 1]))

    def state_dict(self) -> dict:
        st = {"config": self.cfg.to_dict(), "range_deg": [self.lo, self.hi],
              "recent": [[int(x) for x in r] for r in self.recent]}
        if any(self.teacher_recent):        # only where demo_where_teacher_wins recorded any
            st["teacher_recent"] = [[int(x) for x in r] for r in self.teacher_recent]
        return st

    def load_state_dict(self, st: dict) -> None:
        if st["config"] != self.cfg.to_dict() or [float(x) for x in st["range_deg"]] != [self.lo, self.hi]:
            raise ValueError(f"the checkpoint's slope curriculum {st['config']} over {st['range_deg']} deg is not "
                             f"this config's {self.cfg.to_dict()} over {[self.lo, self.hi]} deg: resume with the same "
                             "training.slope_curriculum_* settings, or use another --out")
        for r, xs in zip(self.recent, st["recent"]):
            r.clear()
            r.extend(bool(x) for x in xs)
        for r, xs in zip(self.teacher_recent, st.get("teacher_recent", [[] for _ in self.teacher_recent])):
            r.clear()
            r.extend(bool(x) for x in xs)
