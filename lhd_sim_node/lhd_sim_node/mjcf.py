"""MJCF of the 5:1 scaled LHD, generated from config/lhd_params.yaml (section `machine`).

World frame = pile frame {M}: floor at z = 0, the pile's toe at x = 0, the machine drives
along +x. Joint zeros are the attack pose: the bucket's bottom plate lies on the floor and
the tip frame's x-axis is parallel to it.

Bodies: rear frame (free joint) -> rear wheels, front frame (rigid on the rear frame: the
central articulation does not steer while loading) -> front wheels, boom (hinge about +y:
negative lifts) -> bucket (hinge about -y: positive curls back). Until 2026-11-26 the
articulation was a hinge held by a soft equality constraint (``articulation_hinge=True``
builds that model again): its largest excursion in random episodes was 0.34 mrad, and the
extra degree of freedom and constraint cost 5 % of the simulator's time
(docs/modeling.md, "Speed"). Wheels are spheres in frictional contact
with the floor driven by speed servos with a torque limit, so the machine can stall (pile
resistance above the drive force) or drift (drive torque above what friction transmits).
Boom and bucket are speed servos with force limits, like hydraulics with relief valves.
The pile is not a collision body: it acts only through the FEE force on the bucket.
"""
from __future__ import annotations

from lhd_loading_ros.task.kinematics import FLOOR_GAP, PLATE_T, attack_geometry  # noqa: F401  (one geometry: MJCF and FK)

FEE_ANCHOR_X = -200.0  # m, anchor of the horizontal resistance tendon (far: the tendon stays horizontal)
BODY_ANCHOR_Z = 500.0  # m, anchor of the bucket body's vertical resistance tendon (far: it stays vertical)


def build_mjcf(cfg: dict, articulation_hinge: bool = False) -> str:
    """The MJCF of the machine for config `cfg`; articulation_hinge=True: the earlier model with
    the articulation as a hinge locked by an equality constraint (see the module's docstring)."""
    mc, sim, ctl = cfg["machine"], cfg["sim"], cfg["paper"]["control"]
    task = cfg["task"]
    g = attack_geometry(mc)
    r = g["r"]
    wb, tr = mc["wheelbase"], mc["track"]
    rear_m = mc["chassis_mass"] * mc["rear_mass_fraction"]
    front_m = mc["chassis_mass"] - rear_m
    pivot_x, pivot_z = g["pivot"]
    hinge_dx, hinge_dz = g["reach"], -g["dz_boom"]
    tip_ahead = mc["bucket_tip_ahead_of_hinge"]
    bw = mc["bucket_width"]
    plate_z = -(mc["bucket_hinge_height"] - FLOOR_GAP - PLATE_T / 2)  # plate centre, bucket frame
    top_z = plate_z + PLATE_T / 2
    back_h = mc["bucket_back_height"]
    mc["boom_length"]
    # body frames: rear frame origin at the rear axle (height r); front frame at wb/2 ahead.
    fx = wb / 2

    wm, mu = mc["wheel_mass"], mc["wheel_friction"]

    diff = bool(mc.get("rear_differential", 0))

    def rotor(motor: str, x: float, y: float, armature: float, pad: str) -> str:
        return (f'{pad}<body name="{motor}" pos="{x} {y} 0">\n'
                f'{pad}  <joint name="{motor}" type="hinge" axis="0 1 0" armature="{armature}"/>\n'
                f'{pad}  <inertial pos="0 0 0" mass="1e-6" diaginertia="1e-9 1e-9 1e-9"/>\n'
                f'{pad}</body>\n')

    def wheel(name: str, x: float, y: float, indent: int) -> str:
        """The wheel (tyre in contact with the floor) and, unless the rear differential drives
        it, its own drive motor's rotor beside it on the same frame (drive_tendons couples the
        two; docs/modeling.md, "Drive and drift")."""
        pad = " " * indent
        out = (f'{pad}<body name="{name}" pos="{x} {y} 0">\n'
               f'{pad}  <joint name="{name}" type="hinge" axis="0 1 0"/>\n'
               f'{pad}  <geom name="{name}" type="sphere" size="{r}" mass="{wm}" contype="0" '
               f'conaffinity="1" friction="{mu} 0.005 0.0001" rgba="0.1 0.1 0.1 1"/>\n'
               f'{pad}</body>\n')
        if diff and name in ("wheel_rl", "wheel_rr"):
            return out
        return out + rotor(name.replace("wheel", "motor"), x, y, mc["motor_armature"], pad)

    # The paper's machine: "the rear wheels share a single motor and are connected to a
    # differential, whilst each front wheel has an independent motor" (rear_differential: 1).
    # The rear motor's rotor turns at the mean of the two rear wheels' speeds (an open
    # differential: tendon motor_r - (wheel_rl + wheel_rr) / 2) and gives each of them half its
    # torque, so each rear wheel still gets up to wheel_torque_limit (the tendon's limit is
    # twice it), the rotor has two wheels' inertia and gain, and a wheel that loses grip takes
    # the other's torque down with it, as an open differential does.
    rear_rotor = rotor("motor_r", 0.0, 0.0, 2 * mc["motor_armature"], " " * 6) if diff else ""

    # Drive (docs/modeling.md, "Drive and drift"): each wheel's motor is a speed servo on its own
    # rotor (velocity actuator, not force-limited: MuJoCo 3.3's implicitfast integrator folds a
    # velocity actuator's kv into the implicit step even while its force is clamped, which made a
    # torque-limited wheel servo lag its rolling wheel by a timestep-dependent slip); the rotor turns
    # the wheel through a fixed tendon whose frictionloss is the motor's torque limit (current
    # limit): the wheel gets up to that torque and the rotor slips past it beyond. solreffriction's
    # time constant (8 ms = 2 x the largest timestep used) is fixed so that MuJoCo never rescales it
    # with the timestep.
    tq = mc["wheel_torque_limit"]
    friction = 'solreffriction="0.008 1" solimpfriction="0.99 0.99 0.001"'
    own = ("fl", "fr") if diff else ("rl", "rr", "fl", "fr")
    drive_tendons = "".join(
        f'    <fixed name="drive_{w}" frictionloss="{tq}" {friction}>'
        f'<joint joint="motor_{w}" coef="1"/><joint joint="wheel_{w}" coef="-1"/></fixed>\n'
        for w in own)
    drive_actuators = "".join(
        f'    <velocity name="wheel_{w}" joint="motor_{w}" kv="{mc["wheel_kv"]}" '
        f'ctrlrange="{ctl["wheels_min"]} {ctl["wheels_max"]}"/>\n'
        for w in own)
    if diff:
        drive_tendons = (f'    <fixed name="drive_r" frictionloss="{2 * tq}" {friction}><joint joint="motor_r" coef="1"/>'
                         f'<joint joint="wheel_rl" coef="-0.5"/><joint joint="wheel_rr" coef="-0.5"/></fixed>\n'
                         + drive_tendons)
        drive_actuators = (f'    <velocity name="wheel_r" joint="motor_r" kv="{2 * mc["wheel_kv"]}" '
                           f'ctrlrange="{ctl["wheels_min"]} {ctl["wheels_max"]}"/>\n' + drive_actuators)

    articulation = lock = ""
    if articulation_hinge:
        articulation = '        <joint name="articulation" type="hinge" axis="0 0 1" range="-0.7 0.7"/>\n'
        lock = ('  <equality>\n    <joint name="articulation_lock" joint1="articulation" polycoef="0 0 0 0 0"/>\n'
                '  </equality>\n')

    return f"""
<mujoco model="lhd_scaled_5to1">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{sim['timestep']}" integrator="implicitfast" cone="pyramidal"/>
  <size memory="2M"/>
  <default>
    <geom contype="0" conaffinity="0" friction="0.1 0.005 0.0001" rgba="0.9 0.7 0.1 1"/>
    <joint damping="0"/>
  </default>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1"/>
    <geom name="floor" type="plane" size="0 0 0.05" contype="1" conaffinity="0" rgba="0.5 0.5 0.5 1"/>
    <site name="fee_anchor" pos="{FEE_ANCHOR_X} 0 0.1"/>
    <site name="body_anchor" pos="0.5 0 {BODY_ANCHOR_Z}"/>
    <body name="rear_frame" pos="0 0 {r}">
      <freejoint name="base"/>
      <inertial pos="{-mc['rear_com_behind_axle']} 0 0.12" mass="{rear_m:.4f}" diaginertia="{rear_m*0.03:.4f} {rear_m*0.04:.4f} {rear_m*0.05:.4f}"/>
      <geom name="rear_body" type="box" pos="0 0 0.12" size="0.3 0.17 0.1" mass="0"/>
      <site name="base_link" pos="0 0 0"/>
{wheel("wheel_rl", 0.0, tr / 2, 6)}{wheel("wheel_rr", 0.0, -tr / 2, 6)}{rear_rotor}      <body name="front_frame" pos="{fx} 0 0">
{articulation}        <inertial pos="{fx*0.6:.4f} 0 0.12" mass="{front_m:.4f}" diaginertia="{front_m*0.03:.4f} {front_m*0.04:.4f} {front_m*0.05:.4f}"/>
        <geom name="front_body" type="box" pos="{fx*0.6:.4f} 0 0.12" size="0.3 0.17 0.1" mass="0"/>
{wheel("wheel_fl", fx, tr / 2, 8)}{wheel("wheel_fr", fx, -tr / 2, 8)}        <body name="boom" pos="{pivot_x - fx:.5f} 0 {pivot_z - r:.5f}">
          <joint name="boom" type="hinge" axis="0 1 0" range="{task['boom_angle_min']} {task['boom_angle_max']}" armature="0.05"/>
          <geom name="boom" type="capsule" fromto="0 0 0 {hinge_dx:.5f} 0 {hinge_dz:.5f}" size="0.03" mass="{mc['boom_mass']}"/>
          <body name="bucket" pos="{hinge_dx:.5f} 0 {hinge_dz:.5f}">
            <joint name="bucket" type="hinge" axis="0 -1 0" range="{task['bucket_angle_min']} {task['bucket_angle_max']}" armature="0.05" solreffriction="0.01 1" solimpfriction="0.99 0.999 0.001"/>
            <inertial pos="{tip_ahead*0.4:.4f} 0 {plate_z + back_h*0.3:.4f}" mass="{mc['bucket_mass']}" diaginertia="0.25 0.3 0.3"/>
            <geom name="bucket_plate" type="box" pos="{tip_ahead/2:.5f} 0 {plate_z:.5f}" size="{tip_ahead/2:.5f} {bw/2:.4f} {PLATE_T/2}" mass="0" contype="0" conaffinity="1" friction="{mc['bucket_floor_friction']} 0.005 0.0001"/>
            <geom name="bucket_back" type="box" pos="0 0 {top_z + back_h/2:.5f}" size="{PLATE_T/2} {bw/2:.4f} {back_h/2:.4f}" mass="0"/>
            <geom name="bucket_side_l" type="box" pos="{tip_ahead/2:.5f} {bw/2:.4f} {top_z + back_h/4:.5f}" size="{tip_ahead/2:.5f} {PLATE_T/2} {back_h/4:.4f}" mass="0"/>
            <geom name="bucket_side_r" type="box" pos="{tip_ahead/2:.5f} {-bw/2:.4f} {top_z + back_h/4:.5f}" size="{tip_ahead/2:.5f} {PLATE_T/2} {back_h/4:.4f}" mass="0"/>
            <site name="tip" pos="{tip_ahead:.5f} 0 {top_z:.5f}"/>
            <site name="bottom" pos="0 0 {plate_z - PLATE_T/2:.5f}"/>
            <site name="body_lift" pos="0 0 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    <!-- Horizontal pile resistance: a nearly horizontal tendon from a far anchor to the tip whose
         frictionloss is set to the FEE's horizontal component at every FEE update. Dry friction is a
         constraint in MuJoCo: it stops the bucket without creep and never pushes it back. -->
    <spatial name="fee_x" frictionloss="0" solreffriction="0.01 1" solimpfriction="0.99 0.999 0.001">
      <site site="fee_anchor"/>
      <site site="tip"/>
    </spatial>
    <!-- The whole bucket in the pile (bucket_body.py): breakout of the material over the opening
         resists lifting (body_z, vertical from a far anchor above to the bucket joint) and the
         heel ploughing below the lip's cut resists driving on (body_x, horizontal to the heel);
         both frictionloss limits are set every FEE update, as for fee_x. -->
    <spatial name="body_z" frictionloss="0" solreffriction="0.01 1" solimpfriction="0.99 0.999 0.001">
      <site site="body_anchor"/>
      <site site="body_lift"/>
    </spatial>
    <spatial name="body_x" frictionloss="0" solreffriction="0.01 1" solimpfriction="0.99 0.999 0.001">
      <site site="fee_anchor"/>
      <site site="bottom"/>
    </spatial>
    <!-- Drive: rotor -> wheel, slipping beyond the motor's torque limit (see build_mjcf). -->
{drive_tendons}  </tendon>
{lock}  <actuator>
    <!-- Wheel motors: speed servos on the rotors; the torque limit is the drive tendons' frictionloss. -->
{drive_actuators}    <!-- Hydraulic joints: the valve command is a speed; the oil column holds the joint where it is
         (integrated-velocity position servo), up to the relief force. -->
    <intvelocity name="boom" joint="boom" kp="{mc['boom_kp']}" kv="{mc['boom_kv']}" forcerange="{-mc['boom_force_limit']} {mc['boom_force_limit']}" ctrlrange="{ctl['boom_min']} {ctl['boom_max']}" actrange="{task['boom_angle_min']} {task['boom_angle_max']}"/>
    <intvelocity name="bucket" joint="bucket" kp="{mc['bucket_kp']}" kv="{mc['bucket_kv']}" forcerange="{-mc['bucket_force_limit']} {mc['bucket_force_limit']}" ctrlrange="{ctl['bucket_min']} {ctl['bucket_max']}" actrange="{task['bucket_angle_min']} {task['bucket_angle_max']}"/>
  </actuator>
</mujoco>
"""
