"""The machine state the task needs, whoever measures it (simulator or sensors)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class LhdState:
    """Quantities in the pile frame {M}, SI units, radians.

    phi_shovel: pitch of the bucket tip frame (0 in the attack pose, positive = curled
    back / tip up). phi_boom: boom joint (0 in the attack pose, negative = lifted).
    phi_bucket: bucket joint (0 in the attack pose, positive = curled back).
    """
    x_shovel: float
    y_shovel: float
    z_shovel: float
    phi_shovel: float
    v_x: float
    drift: bool
    phi_boom: float
    dphi_boom: float
    phi_bucket: float
    dphi_bucket: float
    x_bottom: float = 0.0
    z_bottom: float = 0.0
    drift_front: bool = False
    drift_rear: bool = False
