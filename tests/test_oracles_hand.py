"""Independent oracles written in the test (issue 31 item 2): figures the code computes checked
against numbers worked by hand from the definitions, or against a plain reference written here,
never against the code's own output.

- ISO 230-2 (camsmooth.diagnosis.iso230): two small runs worked by hand from the standard's
  definitions (module docstring of iso230: means, sample standard deviations, B_j = x̄↑ - x̄↓,
  R_j = max(2 s↑ + 2 s↓ + |B_j|, 4 s↑, 4 s↓), B = max |B_j|, E, M, A): one whose reversals are all
  negative and one with both signs, and targets where a unidirectional repeatability is the
  largest.
- The significance rule's batch statistics (camsmooth.diagnosis.significance.batch_sum_sd)
  against a plain loop over the batches.
- Each dialect's path-tolerance and TCP words (camsmooth.post, one module per dialect) against the controller
  manual's text, quoted beside the check.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from camsmooth.diagnosis import iso230 as I
from camsmooth.diagnosis.significance import batch_sum_sd

UM = 1e-3  # mm per micrometre


# ---- ISO 230-2 worked by hand ----------------------------------------------------------------------
def _run(approaches: dict[tuple[float, int], list[float]]) -> I.Run:
    """A Run from {(target mm, direction): [deviations in um, one per run]}."""
    t, d, r, x = [], [], [], []
    for (target, direction), devs in approaches.items():
        for k, v in enumerate(devs):
            t.append(target)
            d.append(direction)
            r.append(k + 1)
            x.append(v * UM)
    return I.Run(np.array(t), np.array(d), np.array(r), np.array(x))


# Run 1 (deviations in um), three approaches per target and direction:
#   target   0: up [-4, 0, 4]   mean  0, s = sqrt((16+0+16)/2) = 4      R↑ = 16
#               down [0, 1, 2]  mean  1, s = sqrt((1+0+1)/2)   = 1      R↓ = 4
#               B_0 = 0 - 1 = -1; 2s↑ + 2s↓ + |B| = 8 + 2 + 1 = 11  -> R_0 = max(11, 16, 4) = 16
#   target 100: up [1, 2, 3]    mean  2, s = 1                          R↑ = 4
#               down [4, 5, 6]  mean  5, s = 1                          R↓ = 4
#               B_1 = 2 - 5 = -3; 2 + 2 + 3 = 7                     -> R_1 = max(7, 4, 4) = 7
#   target 200: up [-7, -6, -5] mean -6, s = 1; down [-5, -3, -1] mean -3, s = sqrt((4+0+4)/2) = 2
#               B_2 = -6 - (-3) = -3; 2 + 4 + 3 = 9; R↑ = 4, R↓ = 8  -> R_2 = 9
# Axis: B = max |B_j| = 3 (every B_j negative: the carriage stops short); B̄ = (-1 - 3 - 3) / 3 = -7/3
#   R = max R_j = 16 (a unidirectional repeatability, not the bidirectional sum, is the largest)
#   R↑ = 16, R↓ = 8
#   E↑ = 2 - (-6) = 8; E↓ = 5 - (-3) = 8; E = max(0, 1, 2, 5, -6, -3) - min(...) = 5 - (-6) = 11
#   x̄_j = (0+1)/2 = 0.5, (2+5)/2 = 3.5, (-6-3)/2 = -4.5 -> M = 3.5 - (-4.5) = 8
#   A↑: x̄↑ + 2s↑ = 8, 4, -4; x̄↑ - 2s↑ = -8, 0, -8 -> A↑ = 8 - (-8) = 16
#   A↓: x̄↓ + 2s↓ = 3, 7, 1;  x̄↓ - 2s↓ = -1, 3, -7 -> A↓ = 7 - (-7) = 14
#   A = max(8, 4, -4, 3, 7, 1) - min(-8, 0, -8, -1, 3, -7) = 8 - (-8) = 16
RUN1 = {(0.0, 1): [-4, 0, 4], (0.0, -1): [0, 1, 2], (100.0, 1): [1, 2, 3], (100.0, -1): [4, 5, 6],
        (200.0, 1): [-7, -6, -5], (200.0, -1): [-5, -3, -1]}
HAND1 = dict(mean_up=(0, 2, -6), mean_down=(1, 5, -3), s_up=(4, 1, 1), s_down=(1, 1, 2), reversal=(-1, -3, -3),
             repeat_up=(16, 4, 4), repeat_down=(4, 4, 8), repeat_bi=(16, 7, 9), mean_bi=(0.5, 3.5, -4.5),
             B=3, B_mean=-7 / 3, R_up=16, R_down=8, R=16, E_up=8, E_down=8, E=11, M=8, A_up=16, A_down=14, A=16)

# Run 2: both signs of reversal, the largest |B_j| negative, a unidirectional R largest at one target
#   target  10: up [10, 12]  mean 11, s = sqrt(2)       R↑ = 4 sqrt 2
#               down [0, 2]  mean  1, s = sqrt(2)       R↓ = 4 sqrt 2
#               B = 11 - 1 = +10; 2 sqrt2 + 2 sqrt2 + 10 = 10 + 4 sqrt 2  -> R = 10 + 4 sqrt 2
#   target  20: up [0, 0]    mean  0, s = 0             R↑ = 0
#               down [8, 20] mean 14, s = sqrt(72) = 6 sqrt 2, R↓ = 24 sqrt 2 (33.94)
#               B = -14; 0 + 12 sqrt 2 + 14 = 30.97 < 24 sqrt 2           -> R = 24 sqrt 2
# Axis: B = 14 (the negative one); B̄ = (10 - 14) / 2 = -2; R = 24 sqrt 2; E↑ = 11, E↓ = 13,
#   E = 14 - 0 = 14; x̄_j = 6, 7 -> M = 1
#   A↑: 11 + 2 sqrt2, 0 ; 11 - 2 sqrt2, 0 -> 11 + 2 sqrt 2
#   A↓: 1 + 2 sqrt2, 14 + 12 sqrt2 ; 1 - 2 sqrt2, 14 - 12 sqrt2 -> 24 sqrt 2
#   A = (14 + 12 sqrt2) - (14 - 12 sqrt2) = 24 sqrt 2
R2 = math.sqrt(2.0)
RUN2 = {(10.0, 1): [10, 12], (10.0, -1): [0, 2], (20.0, 1): [0, 0], (20.0, -1): [8, 20]}
HAND2 = dict(mean_up=(11, 0), mean_down=(1, 14), s_up=(R2, 0), s_down=(R2, 6 * R2), reversal=(10, -14),
             repeat_up=(4 * R2, 0), repeat_down=(4 * R2, 24 * R2), repeat_bi=(10 + 4 * R2, 24 * R2), mean_bi=(6, 7),
             B=14, B_mean=-2, R_up=4 * R2, R_down=24 * R2, R=24 * R2, E_up=11, E_down=13, E=14, M=1,
             A_up=11 + 2 * R2, A_down=24 * R2, A=24 * R2)


def _mirrored(approaches: dict) -> dict:
    """The same run with every deviation negated and the directions swapped: x̄↑' = -x̄↓ and
    x̄↓' = -x̄↑, so B_j' = x̄↑' - x̄↓' = -x̄↓ + x̄↑ = B_j, the s swap sides, the means x̄_j change
    sign: B, R, E, M and A are unchanged."""
    return {(t, -d): [-v for v in devs] for (t, d), devs in approaches.items()}


@pytest.mark.parametrize("approaches, hand", [(RUN1, HAND1), (RUN2, HAND2)], ids=["negative-reversals", "both-signs"])
def test_iso230_figures_match_the_hand_worked_example(approaches, hand):
    r = I.evaluate(_run(approaches))
    for name, want in hand.items():
        got = getattr(r, name)
        want_mm = tuple(v * UM for v in want) if isinstance(want, tuple) else want * UM
        assert got == pytest.approx(want_mm, abs=1e-12), name


def test_iso230_the_reversal_value_is_the_largest_magnitude_whatever_its_sign():
    """B = max |B_j|: the same run with up and down swapped (every B_j changes sign) has the same B
    and R and the opposite B̄; all reversals negative still give a positive B."""
    swapped = {(t, -d): devs for (t, d), devs in RUN1.items()}
    a, b = I.evaluate(_run(RUN1)), I.evaluate(_run(swapped))
    assert a.B == pytest.approx(3 * UM) and b.B == pytest.approx(3 * UM)
    assert b.B_mean == pytest.approx(-a.B_mean)
    assert a.R == pytest.approx(b.R) == pytest.approx(16 * UM)
    m = I.evaluate(_run(_mirrored(RUN2)))
    assert m.reversal == pytest.approx(tuple(v * UM for v in HAND2["reversal"]))
    assert (m.B, m.R, m.E, m.M, m.A) == pytest.approx((14 * UM, 24 * R2 * UM, 14 * UM, 1 * UM, 24 * R2 * UM))


# ---- batch means, against a plain loop -----------------------------------------------------------------
def _batch_sd_reference(y: list[float], m: int) -> float:
    """Batch-means standard error of sum(y): M contiguous batches, batch k from floor(k n / M) to
    floor((k + 1) n / M); each batch sum compared with what a batch of its length would hold at the
    overall mean; Var = M / (M - 1) sum (B_k - L_k ybar)^2."""
    n = len(y)
    ybar = sum(y) / n
    acc = 0.0
    for k in range(m):
        lo, hi = (k * n) // m, ((k + 1) * n) // m
        acc += (sum(y[lo:hi]) - (hi - lo) * ybar) ** 2
    return math.sqrt(m / (m - 1) * acc)


@pytest.mark.parametrize("n", [40, 45, 57, 103])
def test_batch_sum_sd_matches_a_plain_reference(n):
    """Unequal batches (n not a multiple of 10) on a series with a large mean: each batch sum is
    compared with its own length times the mean (a batch one sample longer holds one mean more)."""
    rng = np.random.default_rng(n)
    y = 5.0 + rng.normal(0.0, 1.0, n) + np.sin(np.arange(n) / 3.0)
    assert batch_sum_sd(y) == pytest.approx(_batch_sd_reference(y.tolist(), 10), rel=1e-12)
    assert batch_sum_sd(y, 4) == pytest.approx(_batch_sd_reference(y.tolist(), 4), rel=1e-12)
    both = batch_sum_sd(np.column_stack([y, -2.0 * y + 1.0]))
    assert both == pytest.approx([_batch_sd_reference(y.tolist(), 10),
                                  _batch_sd_reference((-2.0 * y + 1.0).tolist(), 10)], rel=1e-12)


def test_batch_sum_sd_of_a_constant_series_is_zero():
    """A constant series has no scatter about its mean: its sum is known exactly, batch lengths
    4 and 5 or not."""
    assert batch_sum_sd(np.full(45, 3.0)) == pytest.approx(0.0, abs=1e-12)


# ---- controller words against the manuals ------------------------------------------------------------
def _program(tmp_path, dialect: str, mode: str, tol: float) -> list[str]:
    from camsmooth.machine.axes import RotaryValues
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.posting import write_gcode
    from camsmooth.smoothing.result import MethodResult

    machine = load_machine(None)
    n = 6
    x = np.linspace(-5.0, 5.0, n)
    cl = np.column_stack([x, np.zeros(n), np.full(n, 10.0)])
    b = np.radians(np.linspace(-5.0, 5.0, n))
    a = np.zeros(n)
    T = machine.tool_axis_np(a, b)
    z0 = np.zeros(n)
    m = MethodResult(method="nlp", rows=np.zeros(n, int), idx=np.arange(n), t=z0, cc=cl, normals=T, cl=cl, axis=T,
                     lead=z0, tilt=z0, rotary=RotaryValues.of(("A", "B"), a, b),
                     rotary_vel=RotaryValues.zeros(("A", "B"), n), rotary_acc=RotaryValues.zeros(("A", "B"), n),
                     xyz=machine.linear_axes(cl, a, b), delta=z0, lift=z0, lead_window=np.zeros((n, 2)),
                     tilt_window=np.zeros((n, 2)), compound_acc=z0)
    cutter = SimpleNamespace(R=3.0, r=1.0, shank_length=40.0, diameter=8.0)
    p = write_gcode(tmp_path / f"{dialect}.nc", m, machine, cutter, 1000.0, dialect=dialect, mode=mode,
                    tolerance=tol)
    return p.read_text().splitlines()


def _numbers(line: str) -> list[float]:
    import re

    return [float(v) for v in re.findall(r"[-+]?\d+\.?\d*", line)]


def test_siemens_cycle832_carries_the_tolerance(tmp_path):
    """SINUMERIK One Programming Manual 12/2019 (6FC5398-2EP40-0BA0), section 3.25 "Programming
    cycles externally", CYCLE832 (high-speed settings), parameter 1: "Tolerance <S_TOL> REAL
    Contour tolerance. The contour tolerance corresponds to the axis tolerance of the geometry
    axes"; parameter 2 <S_TOLM>: the machining type (_FINISH = finishing). So the first argument is
    the user's whole tolerance (mm under G71), not a share of it; TRAORI / TRAFOOF switch the
    orientation transformation (TCP) on and off."""
    tol = 0.02
    lines = _program(tmp_path, "siemens", "tcp", tol)
    calls = [ln for ln in lines if ln.strip().startswith("CYCLE832")]
    assert len(calls) == 1, calls
    args = calls[0].strip()[len("CYCLE832("):-1].split(",")
    assert float(args[0]) == pytest.approx(tol, abs=1e-9)
    assert args[1].strip() == "_FINISH"
    assert "TRAORI" in [ln.strip() for ln in lines] and "TRAFOOF" in [ln.strip() for ln in lines]
    assert lines.index(calls[0]) < next(k for k, ln in enumerate(lines) if ln.strip() == "TRAORI")


def test_heidenhain_cycle32_carries_the_tolerance(tmp_path):
    """HEIDENHAIN TNC 640 User's Manual, Cycle Programming, cycle 32 TOLERANCE: "T: permissible
    contour deviation" (mm in a metric program), HSC-MODE 0 = finishing; FUNCTION TCPM switches the
    tool-centre-point management on, FUNCTION RESET TCPM off."""
    tol = 0.015
    lines = [ln.strip() for ln in _program(tmp_path, "heidenhain", "tcp", tol)]
    t = [ln for ln in lines if "CYCL DEF 32.1" in ln]
    assert len(t) == 1 and _numbers(t[0].split("T", 1)[1])[0] == pytest.approx(tol, abs=1e-9)
    assert any("CYCL DEF 32.0 TOLERANCE" in ln for ln in lines)
    assert any("HSC-MODE:0" in ln for ln in lines)
    assert any("FUNCTION TCPM" in ln and "RESET" not in ln for ln in lines)
    assert any("FUNCTION RESET TCPM" in ln for ln in lines)


def test_linuxcnc_g64_blends_within_the_tolerance(tmp_path):
    """LinuxCNC G-code manual, G64: "G64 P- <Q->: P - motion blending tolerance, Q - naive cam
    tolerance": the path may leave the programmed one by up to P, so P (and Q) must not exceed the
    user's tolerance T; both positive (G64 without P blends without a bound)."""
    tol = 0.01
    lines = [ln.strip() for ln in _program(tmp_path, "linuxcnc", "machine", tol)]
    g64 = [ln for ln in lines if ln.startswith("G64")]
    assert len(g64) == 1
    p = _numbers(g64[0].split("P", 1)[1])[0]
    q = _numbers(g64[0].split("Q", 1)[1])[0]
    assert 0 < p <= tol + 1e-12 and 0 < q <= tol + 1e-12
