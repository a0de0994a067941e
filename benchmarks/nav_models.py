"""Writes the two navigation models (benchmarks/models/car_nav.toml, vessel_nav.toml).

The models are plain TOML files (committed); this script is how they were made: the trajectory's IMU inputs are
written once as definitions of t, x0 is those definitions evaluated at t = 0, and the hand-tuned EKF's Q, R, P(0) and
x̂(0) are the diagonals below, expanded into the full matrices the file needs. Rerun it after changing a number here.

    python benchmarks/nav_models.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"

# ---------------------------------------------------------------- shared strapdown kinematics (ENU, FLU body)
KINEMATICS_DEFS = '''# bias-corrected IMU
ox = "wx - bgx"
oy = "wy - bgy"
oz = "wz - bgz"
ax = "fx - bax"
ay = "fy - bay"
az = "fz - baz"
# R(q), body to navigation (|q|^2 times a rotation: an estimate off the unit sphere shows in the outputs)
r11 = "q0**2 + q1**2 - q2**2 - q3**2"
r12 = "2*(q1*q2 - q0*q3)"
r13 = "2*(q1*q3 + q0*q2)"
r21 = "2*(q1*q2 + q0*q3)"
r22 = "q0**2 - q1**2 + q2**2 - q3**2"
r23 = "2*(q2*q3 - q0*q1)"
r31 = "2*(q1*q3 - q0*q2)"
r32 = "2*(q2*q3 + q0*q1)"
r33 = "q0**2 - q1**2 - q2**2 + q3**2"'''

# the IMU of a trajectory given by its ZYX Euler angles phi_t, th_t, psi_t (and rates) and its acceleration aE, aN, aU
IMU_DEFS = '''# body rates of the Euler angles
om_x = "phi_t1 - psi_t1*sin(th_t)"
om_y = "th_t1*cos(phi_t) + psi_t1*sin(phi_t)*cos(th_t)"
om_z = "-th_t1*sin(phi_t) + psi_t1*cos(phi_t)*cos(th_t)"
# specific force in the body frame: R^T (a + g e3), R = Rz(psi_t) Ry(th_t) Rx(phi_t)
e11 = "cos(psi_t)*cos(th_t)"
e12 = "cos(psi_t)*sin(th_t)*sin(phi_t) - sin(psi_t)*cos(phi_t)"
e13 = "cos(psi_t)*sin(th_t)*cos(phi_t) + sin(psi_t)*sin(phi_t)"
e21 = "sin(psi_t)*cos(th_t)"
e22 = "sin(psi_t)*sin(th_t)*sin(phi_t) + cos(psi_t)*cos(phi_t)"
e23 = "sin(psi_t)*sin(th_t)*cos(phi_t) - cos(psi_t)*sin(phi_t)"
e31 = "-sin(th_t)"
e32 = "cos(th_t)*sin(phi_t)"
e33 = "cos(th_t)*cos(phi_t)"
f_x = "e11*aE + e21*aN + e31*aU"
f_y = "e12*aE + e22*aN + e32*aU"
f_z = "e13*aE + e23*aN + e33*aU"
# the quaternion of the trajectory (for x0)
q0_t = "cos(phi_t/2)*cos(th_t/2)*cos(psi_t/2) + sin(phi_t/2)*sin(th_t/2)*sin(psi_t/2)"
q1_t = "sin(phi_t/2)*cos(th_t/2)*cos(psi_t/2) - cos(phi_t/2)*sin(th_t/2)*sin(psi_t/2)"
q2_t = "cos(phi_t/2)*sin(th_t/2)*cos(psi_t/2) + sin(phi_t/2)*cos(th_t/2)*sin(psi_t/2)"
q3_t = "cos(phi_t/2)*cos(th_t/2)*sin(psi_t/2) - sin(phi_t/2)*sin(th_t/2)*cos(psi_t/2)"'''

STRAPDOWN_DYN = '''q0 = "0.5*(-q1*ox - q2*oy - q3*oz)"
q1 = "0.5*(q0*ox + q2*oz - q3*oy)"
q2 = "0.5*(q0*oy - q1*oz + q3*ox)"
q3 = "0.5*(q0*oz + q1*oy - q2*ox)"
px = "vx"
py = "vy"
pz = "vz"
vx = "r11*ax + r12*ay + r13*az"
vy = "r21*ax + r22*ay + r23*az"
vz = "r31*ax + r32*ay + r33*az - g"
bgx = "0"
bgy = "0"
bgz = "0"
bax = "0"
bay = "0"
baz = "0"'''

MAG_OUT = '''mx = "r11*mE + r21*mN + r31*mU"
my = "r12*mE + r22*mN + r32*mU"
mz = "r13*mE + r23*mN + r33*mU"'''

NAV16 = ["q0", "q1", "q2", "q3", "px", "py", "pz", "vx", "vy", "vz", "bgx", "bgy", "bgz", "bax", "bay", "baz"]


def _defs(text: str) -> list[tuple[str, str]]:
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            k, v = line.split("=", 1)
            out.append((k.strip(), v.strip().strip('"')))
    return out


def at_t0(defs_text: str, params: dict[str, float], names: list[str]) -> dict[str, float]:
    """The definitions (functions of t only) evaluated at t = 0, in the order written."""
    env: dict[str, sp.Expr] = {"t": sp.Integer(0), **{k: sp.Float(v) for k, v in params.items()}}
    for k, v in _defs(defs_text):
        try:
            env[k] = sp.sympify(v, locals={s: env[s] for s in env}).subs(env)
        except (sp.SympifyError, TypeError):
            continue
    return {n: float(sp.N(env[n])) for n in names}


def _mat(diag: list[float]) -> str:
    n = len(diag)
    rows = ["[" + ", ".join(f"{diag[i]:.6g}" if i == j else "0.0" for j in range(n)) + "]" for i in range(n)]
    return "[" + ",\n     ".join(rows) + "]"


def _vec(v: list[float]) -> str:
    return "[" + ", ".join(f"{x:.12g}" for x in v) + "]"


def _table(d: dict[str, float]) -> str:
    return "{ " + ", ".join(f"{k} = {v:g}" for k, v in d.items()) + " }"


# ---------------------------------------------------------------- car
CAR_TRAJ = '''# the drive (functions of t only, for the [simulation] inputs): speed V, road grade gam, course chi
# the road is flat until about t = 40 s (tanh ramp), then rolling hills of +-5 % grade
V = "12 + 3*sin(0.07*t)"
V1 = "0.21*cos(0.07*t)"
hill = "(1 + tanh(t - 45))/2"
hill1 = "(1 - tanh(t - 45)**2)/2"
gam = "0.05*sin(0.12*t)*hill"
gam1 = "0.006*cos(0.12*t)*hill + 0.05*sin(0.12*t)*hill1"
chi = "0.3 + 0.05*t + 0.5*sin(0.1*t)"
chi1 = "0.05 + 0.05*cos(0.1*t)"
chi2 = "-0.005*sin(0.1*t)"
# acceleration in the navigation frame, plus g e3
Vh = "V*cos(gam)"
Vh1 = "V1*cos(gam) - V*sin(gam)*gam1"
aE = "Vh1*cos(chi) - Vh*chi1*sin(chi)"
aN = "Vh1*sin(chi) + Vh*chi1*cos(chi)"
aU = "V1*sin(gam) + V*cos(gam)*gam1 + g"
# attitude: heading = course (no side slip), nose up on a climb (a negative pitch in FLU), body roll on the springs
phi_t = "0.015*sin(0.3*t)"
phi_t1 = "0.0045*cos(0.3*t)"
th_t = "-gam"
th_t1 = "-gam1"
psi_t = "chi"
psi_t1 = "chi1"
vE_t = "Vh*cos(chi)"
vN_t = "Vh*sin(chi)"
vU_t = "V*sin(gam)"'''

CAR = dict(
    params={"g": 9.81, "mE": 0.01, "mN": 0.2, "mU": -0.43},
    bg=[0.005, -0.008, 0.01], ba=[0.08, -0.06, 0.1], ks_true=1.03, ks_guess=1.0,
    noise={"gpx": 1.0, "gpy": 1.0, "gpz": 2.0, "wheel": 0.05, "mx": 0.005, "my": 0.005, "mz": 0.005},
    period={"gpx": 0.5, "gpy": 0.5, "gpz": 0.5, "wheel": 0.02, "mx": 0.1, "my": 0.1, "mz": 0.1},
    delay={"gpx": 0.2, "gpy": 0.2, "gpz": 0.2},
    process={"q0": 2e-5, "q1": 2e-5, "q2": 2e-5, "q3": 2e-5, "vx": 0.02, "vy": 0.02, "vz": 0.02},
    initial_std={"bgx": 0.01, "bgy": 0.01, "bgz": 0.01, "bax": 0.15, "bay": 0.15, "baz": 0.15, "ks": 0.05},
    # the hand-tuned EKF (see the file's comments for why)
    hand_Q=[4e-10] * 4 + [1e-6] * 3 + [4e-4] * 3 + [1e-10] * 3 + [1e-8] * 3 + [1e-10],
    hand_P0=[1e-3] * 4 + [4.0, 4.0, 9.0] + [0.25] * 3 + [1e-4] * 3 + [0.0225] * 3 + [0.0025],
    hand_offset={"px": 2.0, "py": -2.0, "pz": 1.0, "vx": 0.3, "vy": -0.3, "vz": 0.1},
)


def car_toml() -> str:
    c = CAR
    names = ["vE_t", "vN_t", "vU_t", "q0_t", "q1_t", "q2_t", "q3_t"]
    v = at_t0(CAR_TRAJ + "\n" + IMU_DEFS, c["params"], names)
    x0 = [v["q0_t"], v["q1_t"], v["q2_t"], v["q3_t"], 0.0, 0.0, 0.0, v["vE_t"], v["vN_t"], v["vU_t"], *c["bg"], *c["ba"]]
    xhat0 = list(x0[:16])
    for k, d in c["hand_offset"].items():
        xhat0[NAV16.index(k)] += d
    xhat0[10:16] = [0.0] * 6
    xhat0.append(c["ks_guess"])
    R = [c["noise"][k] ** 2 for k in ["gpx", "gpy", "gpz", "wheel", "mx", "my", "mz"]]
    bg, ba = c["bg"], c["ba"]
    return f'''# Car navigation, 16 states and an unknown wheel-speed scale (benchmarks/nav_models.py writes this file).
# Strapdown INS as in src/nlobs/models/ins16.toml (Groves (2013), Ch. 5 and 14; Sola (2017) quaternion kinematics):
# ENU navigation frame, FLU body frame, flat earth, q = body-to-navigation Hamilton quaternion, the IMU is the input
# (gyros omega + bg, accelerometers the specific force + ba). Aiding, each at the rate such sensors run on a car:
#   GNSS         gpx, gpy, gpz  position, 2 Hz, arriving 0.2 s late     sigma 1 / 1 / 2 m
#   wheel speed  wheel          ks * forward speed (body x), 50 Hz      sigma 0.05 m/s, ks unknown (tyre radius)
#   magnetometer mx, my, mz     R^T m_n, 10 Hz                          sigma 0.005 G
# The IMU runs at 200 Hz (the 5 ms grid of [simulation]); its noise is the process noise on v and q.
# True biases: gyro ({bg[0]}, {bg[1]}, {bg[2]}) rad/s, accelerometer ({ba[0]}, {ba[1]}, {ba[2]}) m/s^2; true ks = {c["ks_true"]}.
# The drive: 12 +- 3 m/s, turning left at 0 - 0.1 rad/s (about one full turn in 120 s), a flat road for the first
# 40 s, then rolling hills of +-5 % grade; heading = course (no side slip), body roll +-0.015 rad.
name = "car_nav"
description = "Car navigation, 16 states + wheel-speed scale: IMU inputs 200 Hz, GNSS 2 Hz 0.2 s late, wheel speed 50 Hz, magnetometer 10 Hz"
states = {_list(NAV16)}
inputs = ["wx", "wy", "wz", "fx", "fy", "fz"]
outputs = ["gpx", "gpy", "gpz", "wheel", "mx", "my", "mz"]

[parameters]
g = 9.81
mE = 0.01
mN = 0.2
mU = -0.43
ks = {{ value = {c["ks_guess"]}, unknown = true }}

[definitions]
{KINEMATICS_DEFS}
{CAR_TRAJ}
{IMU_DEFS}

[dynamics]
{STRAPDOWN_DYN}

[output]
gpx = "px"
gpy = "py"
gpz = "pz"
wheel = "ks*(r11*vx + r21*vy + r31*vz)"
{MAG_OUT}

[units]
t = "s"
px = "m"
py = "m"
pz = "m"
vx = "m/s"
vy = "m/s"
vz = "m/s"
bgx = "rad/s"
bgy = "rad/s"
bgz = "rad/s"
bax = "m/s^2"
bay = "m/s^2"
baz = "m/s^2"
wx = "rad/s"
wy = "rad/s"
wz = "rad/s"
fx = "m/s^2"
fy = "m/s^2"
fz = "m/s^2"
gpx = "m"
gpy = "m"
gpz = "m"
wheel = "m/s"
mx = "G"
my = "G"
mz = "G"
g = "m/s^2"
mE = "G"
mN = "G"
mU = "G"

[simulation]
t_final = 120.0
dt = 0.005
# x0: the quaternion q0_t..q3_t, position 0, velocity vE_t, vN_t, vU_t at t = 0, then the true biases
x0 = {_vec(x0)}
inputs = {_imu(bg, ba)}
noise = {_table(c["noise"])}
process_noise = {_table(c["process"])}
sample_period = {_table(c["period"])}
delay = {_table(c["delay"])}
initial_std = {_table(c["initial_std"])}
true_parameters = {{ ks = {c["ks_true"]} }}
seed = 3

# The EKF tuned by hand (states in the order above, then ks):
# - Q: the declared process noise where there is one (q: (2e-5)^2 = 4e-10, a gyro's angle random walk of about
#   0.1 deg/sqrt(h); v: 0.02^2 = 4e-4, the accelerometer noise and vibration); 1e-6 on position (no noise enters there: a small allowance for the RK4 and the
#   IMU's sample-and-hold); 1e-10 on the gyro biases and 1e-8 on the accelerometer biases (a bias instability of
#   1e-5 rad/s and 1e-4 m/s^2 per sqrt(s): over 120 s less than a tenth of the bias, so the biases are nearly
#   constant and the filter averages them; larger values let GNSS noise into them); 1e-10 on ks (a constant).
#   Tried first: 1e-8 on q and 2.5e-3 on v with a plant of that noise: the lateral accelerometer bias bay then ends
#   27 % of its initial error off (a velocity random walk of 0.05 m/s/sqrt(s) hides a 0.01 m/s^2 bias over 120 s);
#   with the plant's v noise at 0.02 every bias and ks end within 13 % (bay, the slowest: only the turns separate
#   it from the roll) and the gyro biases within 1 %.
# - R: the declared sensor sigmas squared (GNSS 1, 1, 4 m^2; wheel 2.5e-3; magnetometer 2.5e-5 G^2).
# - P0: the initial errors as one sigma: attitude 1e-3 per quaternion component (x0 from the magnetometer and gravity:
#   about 0.03 rad), position 2 / 2 / 3 m, velocity 0.5 m/s, biases their initial_std (0.01 rad/s, 0.15 m/s^2), ks 0.05.
# - x0: the true position and velocity moved by (2, -2, 1) m and (0.3, -0.3, 0.1) m/s, biases 0, ks 1.
[observers.hand]
kind = "ekf"
mode = "continuous-discrete"
xhat0 = {_vec(xhat0)}
Q = {_mat(c["hand_Q"])}
R = {_mat(R)}
P0 = {_mat(c["hand_P0"])}
'''


def _imu(bg: list[float], ba: list[float]) -> str:
    """The IMU inputs of the trajectory, each plus its bias."""
    terms = [f'{k} = "{e} {"-" if b < 0 else "+"} {abs(b):g}"'
             for k, e, b in zip(["wx", "wy", "wz", "fx", "fy", "fz"], ["om_x", "om_y", "om_z", "f_x", "f_y", "f_z"], [*bg, *ba])]
    return "{ " + ", ".join(terms) + " }"


def _list(names: list[str]) -> str:
    return "[" + ", ".join(f'"{n}"' for n in names) + "]"


# ---------------------------------------------------------------- vessel
VESSEL_TRAJ = '''# the passage (functions of t only, for the [simulation] inputs): ground speed Vh, course chi, heave z_t;
# heading = course + a slowly varying crab angle; roll and pitch in the swell
Vh = "3 + 0.5*sin(0.05*t)"
Vh1 = "0.025*cos(0.05*t)"
chi = "0.2 + 0.03*t + 0.4*sin(0.06*t)"
chi1 = "0.03 + 0.024*cos(0.06*t)"
vU_t = "0.36*cos(0.9*t)"
aE = "Vh1*cos(chi) - Vh*chi1*sin(chi)"
aN = "Vh1*sin(chi) + Vh*chi1*cos(chi)"
aU = "-0.324*sin(0.9*t) + g"
phi_t = "0.06*sin(0.7*t)"
phi_t1 = "0.042*cos(0.7*t)"
th_t = "0.03*sin(0.5*t + 1)"
th_t1 = "0.015*cos(0.5*t + 1)"
psi_t = "chi + 0.05*sin(0.02*t)"
psi_t1 = "chi1 + 0.001*cos(0.02*t)"
vE_t = "Vh*cos(chi)"
vN_t = "Vh*sin(chi)"'''

VESSEL = dict(
    params={"g": 9.81, "mE": 0.0, "mN": 0.18, "mU": -0.45},
    bg=[-0.004, 0.006, 0.003], ba=[-0.05, 0.07, -0.09], cur=[0.3, -0.2],
    noise={"gpx": 1.5, "gpy": 1.5, "gpz": 3.0, "dvx": 0.02, "dvy": 0.02, "dvz": 0.02, "stw": 0.05, "mx": 0.005, "my": 0.005,
           "mz": 0.005},
    period={"gpx": 1.0, "gpy": 1.0, "gpz": 1.0, "dvx": 0.2, "dvy": 0.2, "dvz": 0.2, "stw": 0.1, "mx": 0.1, "my": 0.1,
            "mz": 0.1},
    delay={"gpx": 0.3, "gpy": 0.3, "gpz": 0.3},
    process={"q0": 2e-5, "q1": 2e-5, "q2": 2e-5, "q3": 2e-5, "vx": 0.03, "vy": 0.03, "vz": 0.005, "cE": 0.005, "cN": 0.005},
    initial_std={"bgx": 0.01, "bgy": 0.01, "bgz": 0.01, "bax": 0.1, "bay": 0.1, "baz": 0.1, "cE": 0.5, "cN": 0.5},
    hand_Q=[4e-10] * 4 + [1e-6] * 3 + [9e-4, 9e-4, 2.5e-5] + [1e-10] * 3 + [1e-8] * 3 + [2.5e-5] * 2,
    hand_P0=[1e-3] * 4 + [9.0, 9.0, 16.0] + [0.25] * 3 + [1e-4] * 3 + [0.01] * 3 + [0.25] * 2,
    hand_offset={"px": 3.0, "py": -3.0, "pz": 2.0, "vx": 0.3, "vy": -0.3, "vz": 0.1},
)

VESSEL_STATES = NAV16 + ["cE", "cN"]


def vessel_toml() -> str:
    c = VESSEL
    names = ["vE_t", "vN_t", "vU_t", "q0_t", "q1_t", "q2_t", "q3_t"]
    v = at_t0(VESSEL_TRAJ + "\n" + IMU_DEFS, c["params"], names)
    x0 = [v["q0_t"], v["q1_t"], v["q2_t"], v["q3_t"], 0.0, 0.0, 0.0, v["vE_t"], v["vN_t"], v["vU_t"], *c["bg"], *c["ba"],
          *c["cur"]]
    xhat0 = list(x0)
    for k, d in c["hand_offset"].items():
        xhat0[VESSEL_STATES.index(k)] += d
    xhat0[10:16] = [0.0] * 6
    xhat0[16:18] = [0.0, 0.0]
    outs = ["gpx", "gpy", "gpz", "dvx", "dvy", "dvz", "stw", "mx", "my", "mz"]
    R = [c["noise"][k] ** 2 for k in outs]
    bg, ba, cur = c["bg"], c["ba"], c["cur"]
    return f'''# Surface vessel navigation, 18 states (benchmarks/nav_models.py writes this file): strapdown INS as in
# src/nlobs/models/ins16.toml (ENU, FLU body, q body-to-navigation; Groves (2013) Ch. 5, 14; Sola (2017)) plus the
# horizontal water current (cE, cN, a random walk). The IMU is the input at 100 Hz. Aiding:
#   GNSS      gpx, gpy, gpz   position, 1 Hz, arriving 0.3 s late               sigma 1.5 / 1.5 / 3 m
#   DVL       dvx, dvy, dvz   bottom-track velocity over ground, body frame, 5 Hz  sigma 0.02 m/s
#   log       stw             speed through the water, body x (EM log), 10 Hz     sigma 0.05 m/s
#   compass   mx, my, mz      magnetometer R^T m_n, 10 Hz                         sigma 0.005 G
# True biases: gyro ({bg[0]}, {bg[1]}, {bg[2]}) rad/s, accelerometer ({ba[0]}, {ba[1]}, {ba[2]}) m/s^2; current at t = 0
# ({cur[0]}, {cur[1]}) m/s, then a random walk of 0.005 m/s per sqrt(s).
# The passage: 3 +- 0.5 m/s over ground, course turning left at 0.006 - 0.054 rad/s (a full circle in about 200 s),
# heading = course + a crab angle of +-0.05 rad, heave +-0.4 m at 0.9 rad/s, roll +-0.06 rad, pitch +-0.03 rad.
name = "vessel_nav"
description = "Surface vessel navigation, 18 states: IMU inputs 100 Hz, GNSS 1 Hz 0.3 s late, DVL 5 Hz, EM log 10 Hz, compass 10 Hz, water current"
states = {_list(VESSEL_STATES)}
inputs = ["wx", "wy", "wz", "fx", "fy", "fz"]
outputs = {_list(outs)}

[parameters]
g = 9.81
mE = {c["params"]["mE"]}
mN = {c["params"]["mN"]}
mU = {c["params"]["mU"]}

[definitions]
{KINEMATICS_DEFS}
{VESSEL_TRAJ}
{IMU_DEFS}

[dynamics]
{STRAPDOWN_DYN}
cE = "0"
cN = "0"

[output]
gpx = "px"
gpy = "py"
gpz = "pz"
dvx = "r11*vx + r21*vy + r31*vz"
dvy = "r12*vx + r22*vy + r32*vz"
dvz = "r13*vx + r23*vy + r33*vz"
stw = "r11*(vx - cE) + r21*(vy - cN) + r31*vz"
{MAG_OUT}

[units]
t = "s"
px = "m"
py = "m"
pz = "m"
vx = "m/s"
vy = "m/s"
vz = "m/s"
cE = "m/s"
cN = "m/s"
bgx = "rad/s"
bgy = "rad/s"
bgz = "rad/s"
bax = "m/s^2"
bay = "m/s^2"
baz = "m/s^2"
wx = "rad/s"
wy = "rad/s"
wz = "rad/s"
fx = "m/s^2"
fy = "m/s^2"
fz = "m/s^2"
gpx = "m"
gpy = "m"
gpz = "m"
dvx = "m/s"
dvy = "m/s"
dvz = "m/s"
stw = "m/s"
mx = "G"
my = "G"
mz = "G"
g = "m/s^2"
mE = "G"
mN = "G"
mU = "G"

[simulation]
t_final = 120.0
dt = 0.01
# x0: the quaternion q0_t..q3_t, position 0, velocity vE_t, vN_t, vU_t at t = 0, the true biases, the current
x0 = {_vec(x0)}
inputs = {_imu(bg, ba)}
noise = {_table(c["noise"])}
process_noise = {_table(c["process"])}
sample_period = {_table(c["period"])}
delay = {_table(c["delay"])}
initial_std = {_table(c["initial_std"])}
seed = 5

# The EKF tuned by hand (states in the order above):
# - Q: the declared process noise (q (2e-5)^2 = 4e-10: additive noise on q also moves |q|, and R(q) = |q|^2 x a
#   rotation then leaks gravity into the vertical (with 1e-4 the plant sank 12 m in 120 s), horizontal v 0.03^2 = 9e-4, vertical 0.005^2 (the hull rides the swell), current 0.005^2 = 2.5e-5); 1e-6 on position (an allowance
#   for the RK4 and the IMU's sample-and-hold); 1e-10 and 1e-8 on the gyro and accelerometer biases (nearly constant
#   over the run, as on the car).
# - R: the declared sensor sigmas squared.
# - P0: attitude 1e-3 per quaternion component, position 3 / 3 / 4 m, velocity 0.5 m/s, biases and current their
#   initial_std (0.01 rad/s, 0.1 m/s^2, 0.5 m/s).
# - x0: the true position and velocity moved by (3, -3, 2) m and (0.3, -0.3, 0.1) m/s, biases and current 0.
[observers.hand]
kind = "ekf"
mode = "continuous-discrete"
xhat0 = {_vec(xhat0)}
Q = {_mat(c["hand_Q"])}
R = {_mat(R)}
P0 = {_mat(c["hand_P0"])}
'''


if __name__ == "__main__":
    MODELS.mkdir(exist_ok=True)
    (MODELS / "car_nav.toml").write_text(car_toml())
    (MODELS / "vessel_nav.toml").write_text(vessel_toml())
    print("wrote", MODELS / "car_nav.toml", MODELS / "vessel_nav.toml")
