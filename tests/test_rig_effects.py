"""Rig effects (issue 5, docs/rigs.md): each effect alone against the ideal rig shows the signature
a motor-control engineer looks for; an effect switched off restores the ideal plant bit for bit.

The runs are in-process (tests/test_run_emulator.py's way) on tests/data/effects-steady.yaml:
600 r/min (electrical 40 Hz), then 5 N m. A recording device samples the plant's truth (true
currents, angle, temperatures, DC link) every 10 control periods, next to the firmware's telemetry.
Harmonics are measured by projecting onto the electrical angle over whole electrical periods.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from emu_helpers import raw_messages

from pmsm_hil.emulator.fwlib import EmulatedDevice
from pmsm_hil.emulator.settings import emulator_settings
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile, load_rig
from pmsm_hil.profiles.fluxmap import load_flux_map
from pmsm_hil.profiles.rig import EFFECT_BITS
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile
from pmsm_hil.transport.inproc import InProcessTransport

ROOT = Path(__file__).resolve().parents[1]
RIGS = ROOT / "profiles" / "rigs"
STEADY = ROOT / "tests" / "data" / "effects-steady.yaml"
WINDOW = (0.70, 1.10)  # loaded steady state: 16 electrical periods at 40 Hz


class RecordingDevice(EmulatedDevice):
    """The emulated device, recording the plant's truth averaged over blocks of `every` control
    periods (the mean removes the switching ripple of the current, as a scope's averaging would)."""

    def __init__(self, settings, every: int = 10):
        super().__init__(settings)
        self.every = every
        self.truth: list[dict] = []
        self._acc: list[dict] = []

    def run(self, max_ticks: int):
        ticks, out = 0, []
        while ticks < max_ticks and self.active:
            n, o = super().run(1)
            out.append(o)
            if n == 0:
                break
            ticks += n
            self._acc.append(self.plant_truth())
            if len(self._acc) == self.every:
                rec = {k: float(np.mean([a[k] for a in self._acc])) for k in self._acc[0]}
                mid = self._acc[len(self._acc) // 2]
                for k in ("t_s", "tick", "theta_e_rad", "theta_m_rad"):  # angles are not averaged
                    rec[k] = mid[k]
                self.truth.append(rec)
                self._acc = []
        if not self.active:
            n, o = super().run(0)
            out.append(o)
        return ticks, b"".join(out)


def write_rig(tmp_path: Path, name: str, effects_yaml: str) -> Path:
    p = tmp_path / f"{name}.yaml"
    p.write_text(f'name: "{name}"\nv_dc_v: null\neffects:\n{effects_yaml}')
    return p


def run(rig, out: Path, profile=STEADY, seed=1):
    prof = load_profile(str(profile), rig_override=str(rig))
    settings = emulator_settings(
        prof.motor, prof.rig, seed=seed, baud=prof.link.baud, ts_s=prof.control.ts_s
    )
    dev = RecordingDevice(settings)
    result = run_profile(
        prof, Session(InProcessTransport(settings, device=dev)), out, RunOptions(seed=seed)
    )
    assert result.faults == 0 and result.state == "done", result
    truth = {k: np.array([r[k] for r in dev.truth]) for k in dev.truth[0]}
    return prof, read_log(out), truth


def harmonic_c(x, theta, h):
    """Complex amplitude (phasor) of the h-th harmonic of the electrical angle in x."""
    x, theta = np.asarray(x, float), np.asarray(theta, float)
    return 2.0 * np.mean((x - x.mean()) * np.exp(-1j * h * theta))


def harmonic(x, theta, h, t=None, window=WINDOW):
    """Amplitude of the h-th harmonic of the electrical angle in x over the window."""
    x, theta = np.asarray(x, float), np.asarray(theta, float)
    if t is not None:
        m = (t >= window[0]) & (t < window[1])
        x, theta = x[m], theta[m]
    return abs(harmonic_c(x, theta, h))


def tel(log, window=WINDOW):
    t = log.topic("/pmsm/telemetry")
    m = (t["t_s"] >= window[0]) & (t["t_s"] < window[1])
    return {k: v[m] for k, v in t.items()}


def tru(truth, window=WINDOW):
    m = (truth["t_s"] >= window[0]) & (truth["t_s"] < window[1])
    return {k: v[m] for k, v in truth.items()}


@pytest.fixture(scope="module")
def ideal(tmp_path_factory):
    out = tmp_path_factory.mktemp("ideal") / "ideal.mcap"
    return (*run(RIGS / "ideal.yaml", out), out)


# ----------------------------------------------------------------------------- rig files


def test_shipped_rigs_load_and_each_effect_file_has_one_effect():
    names = set(EFFECT_BITS)
    for name in names:
        rig = load_rig(RIGS / f"effect-{name.replace('_', '-')}.yaml")
        assert rig.enabled_effects == [name]
        assert rig.effects_mask == 1 << EFFECT_BITS[name]
    assert load_rig(RIGS / "ideal.yaml").enabled_effects == []
    # lab-typical's motor is its motor file's: a production spread is for sweeps to draw
    assert set(load_rig(RIGS / "lab-typical.yaml").enabled_effects) == names - {"motor_deviation"}
    assert len(set(EFFECT_BITS.values())) == len(EFFECT_BITS)


def test_off_restores_the_ideal_plant_bit_for_bit(ideal, tmp_path):
    """Every effect listed (at lab-typical sizes) but disabled: the same device messages as ideal."""
    text = (RIGS / "lab-typical.yaml").read_text()
    for name in EFFECT_BITS:
        text = text.replace(f"\n  {name}:\n", f"\n  {name}:\n    enabled: false\n")
    (tmp_path / "maps").mkdir()
    rig = tmp_path / "rigs" / "all-off.yaml"
    rig.parent.mkdir()
    rig.write_text(text)
    os.symlink(
        ROOT / "profiles" / "maps" / "paper-a-ipmsm.csv", tmp_path / "maps" / "paper-a-ipmsm.csv"
    )
    assert load_rig(rig).enabled_effects == []
    _, _, truth = run(rig, tmp_path / "off.mcap")
    truth_ideal = ideal[2]
    assert raw_messages(tmp_path / "off.mcap") == raw_messages(ideal[3])
    for k in truth:
        assert np.array_equal(truth[k], truth_ideal[k]), k


def test_truth_and_metadata_report_the_effects(tmp_path):
    rig = write_rig(
        tmp_path, "two", "  sensor_offset: {i_a_a: 0.1}\n  iron_loss: {r_fe_ohm: 250}\n"
    )
    _prof, log, _ = run(rig, tmp_path / "two.mcap")
    mask = (1 << EFFECT_BITS["sensor_offset"]) | (1 << EFFECT_BITS["iron_loss"])
    assert set(log.topic("/sim/truth")["effects"].tolist()) == {mask}
    meta = log.metadata["rig_effects"]
    assert meta["effects"] == "sensor_offset,iron_loss"
    assert meta["effects_mask"] == str(mask)
    assert meta["sensor_offset.i_a_a"] == "0.1" and meta["iron_loss.r_fe_ohm"] == "250.0"
    assert "dead_time.dead_time_s" not in meta  # only the effects in force


# ----------------------------------------------------------------------------- signatures


def test_sensor_offset_gives_the_first_harmonic(ideal, tmp_path):
    o_a, o_b = 0.3, -0.2
    rig = write_rig(
        tmp_path, "off", f"  sensor_offset: {{i_a_a: {o_a}, i_b_a: {o_b}, i_c_a: 0.0}}\n"
    )
    _, _, truth = run(rig, tmp_path / "o.mcap")
    t, ti = tru(truth), tru(ideal[2])
    # the firmware's Clarke uses channels a and b: an offset vector fixed in the stator frame,
    # which the current loop regulates away from the measurement, so the true currents carry it
    # rotating at the electrical frequency
    off = math.hypot(o_a, (o_a + 2.0 * o_b) / math.sqrt(3.0))
    for ax in ("i_d_a", "i_q_a"):
        a1 = harmonic(t[ax], t["theta_e_rad"], 1)
        a1_ideal = harmonic(ti[ax], ti["theta_e_rad"], 1)
        assert a1 == pytest.approx(off, rel=0.25), ax
        assert a1 > 10 * a1_ideal, ax
        assert a1 > 3 * harmonic(t[ax], t["theta_e_rad"], 2), ax


def test_sensor_gain_mismatch_gives_the_second_harmonic(ideal, tmp_path):
    g = 0.05
    rig = write_rig(
        tmp_path, "gain", f"  sensor_gain: {{i_a_gain: 1.0, i_b_gain: {1 + g}, i_c_gain: 1.0}}\n"
    )
    _, _, truth = run(rig, tmp_path / "g.mcap")
    t, ti = tru(truth), tru(ideal[2])
    i_s = math.hypot(t["i_d_a"].mean(), t["i_q_a"].mean())
    for ax in ("i_d_a", "i_q_a"):
        a2 = harmonic(t[ax], t["theta_e_rad"], 2)
        assert a2 > 4 * harmonic(ti[ax], ti["theta_e_rad"], 2), ax
        assert a2 > 3 * harmonic(t[ax], t["theta_e_rad"], 1), ax
        # a gain error g on channel b scales i_beta by up to g (2/sqrt3 i_b / i_beta); in dq it
        # splits into a DC part and a 2nd harmonic of about g |i| / sqrt3
        assert 0.3 * g * i_s / math.sqrt(3) < a2 < 2.0 * g * i_s / math.sqrt(3), ax


def test_flux_harmonics_give_the_sixth_harmonic(ideal, tmp_path):
    e5, e7 = 0.05, 0.03
    rig = write_rig(tmp_path, "fh", f"  flux_harmonics: {{emf5_rel: {e5}, emf7_rel: {e7}}}\n")
    prof, _log, truth = run(rig, tmp_path / "fh.mcap")
    t, ti = tru(truth), tru(ideal[2])
    # torque ripple at 6 f_e (the MPCC regulates the currents hard, so the harmonic shows in the
    # torque and in the voltage rather than in the currents)
    t6 = harmonic(t["torque_nm"], t["theta_e_rad"], 6)
    assert t6 > 2 * harmonic(ti["torque_nm"], ti["theta_e_rad"], 6)
    assert t6 > 5 * harmonic(t["torque_nm"], t["theta_e_rad"], 5)
    # the back-EMF in dq: e_d6 = w psi_f (e5 + e7), e_q6 = w psi_f (e7 - e5): the voltage the
    # current loop applies carries them
    w_psi = prof.motor.psi_f_wb * 600 / 60 * 2 * math.pi * prof.motor.pole_pairs
    # (the 8-vector MPCC's own angle-periodic pattern is the same in both runs: compare phasors)
    ud6 = abs(
        harmonic_c(t["u_d_v"], t["theta_e_rad"], 6) - harmonic_c(ti["u_d_v"], ti["theta_e_rad"], 6)
    )
    uq6 = abs(
        harmonic_c(t["u_q_v"], t["theta_e_rad"], 6) - harmonic_c(ti["u_q_v"], ti["theta_e_rad"], 6)
    )
    assert ud6 == pytest.approx(w_psi * (e5 + e7), rel=0.25)
    assert uq6 == pytest.approx(w_psi * abs(e7 - e5), rel=0.5)


def test_dead_time_gives_the_sixth_harmonic_and_follows_the_current_sign(ideal, tmp_path):
    rig = write_rig(
        tmp_path, "dt", "  dead_time: {dead_time_s: 3.0e-6, v_drop_v: 1.5, i_dt_a: 0.5}\n"
    )
    _, _log, truth = run(rig, tmp_path / "dt.mcap")
    t = tru(truth)
    th = t["theta_e_rad"]
    c, s = np.cos(th), np.sin(th)
    # the inverter's distortion voltage, per phase (legs minus their mean: the neutral floats)
    legs = np.stack([t["v_dist_a_v"], t["v_dist_b_v"], t["v_dist_c_v"]])
    ph = legs - legs.mean(axis=0)
    i_al, i_be = c * t["i_d_a"] - s * t["i_q_a"], s * t["i_d_a"] + c * t["i_q_a"]
    i3 = np.stack(
        [i_al, -0.5 * i_al + math.sqrt(3) / 2 * i_be, -0.5 * i_al - math.sqrt(3) / 2 * i_be]
    )
    # it follows the current sign, against the current (volts lost in the current's direction)
    corr = np.corrcoef(ph.ravel(), np.sign(i3).ravel())[0, 1]
    assert corr < -0.85, corr
    assert np.mean(ph * np.sign(i3)) < -1.0
    # in dq: a DC part and a 6th harmonic (the six-step pattern of the three current signs)
    u_al = (2 * legs[0] - legs[1] - legs[2]) / 3
    u_be = (legs[1] - legs[2]) / math.sqrt(3)
    ud, uq = c * u_al + s * u_be, -s * u_al + c * u_be
    d6 = harmonic(ud, th, 6) + harmonic(uq, th, 6)
    assert d6 > 0.1 * abs(complex(ud.mean(), uq.mean()))
    assert d6 > 5 * (
        harmonic(ud, th, 5) + harmonic(uq, th, 5) + harmonic(ud, th, 1) + harmonic(uq, th, 1)
    )
    assert np.all(tru(ideal[2])["v_dist_a_v"] == 0.0)


def test_a_flux_map_runs_the_plant_at_map_substeps():
    """RK4 in the currents missed a flux map's voltage equation by tenths of a volt under FCS at one
    step per period; the plant integrates a map in the flux linkage, where one step meets it
    (firmware/tests/test_plant_effects.c, test_map_substeps): the emulator integrates map rigs at
    MAP_SUBSTEPS, others at one."""
    from pmsm_hil.emulator.settings import MAP_SUBSTEPS

    assert MAP_SUBSTEPS >= 1
    for rig, want in (
        ("lab-typical", MAP_SUBSTEPS),
        ("effect-saturation", MAP_SUBSTEPS),
        ("default", 1),
        ("effect-dead-time", 1),
    ):
        prof = load_profile(str(STEADY), rig_override=str(RIGS / f"{rig}.yaml"))
        s = emulator_settings(prof.motor, prof.rig)
        assert s["substeps"] == want, rig
        EmulatedDevice(s)  # the sim board takes it


def test_saturation_lowers_the_incremental_lq_as_in_the_map(tmp_path):
    rig = load_rig(RIGS / "effect-saturation.yaml")
    fm = load_flux_map(rig.map_path())
    prof = load_profile(str(STEADY), rig_override=str(RIGS / "effect-saturation.yaml"))
    dev = EmulatedDevice(emulator_settings(prof.motor, prof.rig))
    j0 = int(np.argmin(np.abs(fm.i_d_a)))
    iq = fm.i_q_a
    lq_map = np.gradient(fm.psi_q_wb[:, j0], iq)  # the map's own incremental L_q at i_d = 0
    lq_plant = np.array([dev.plant_flux(float(fm.i_d_a[j0]), float(q))["l_qq_h"] for q in iq])
    inner = np.abs(iq) <= 12.5
    assert np.allclose(lq_plant[inner], lq_map[inner], rtol=0.05, atol=2e-4)
    small = dev.plant_flux(0.0, 0.0)["l_qq_h"]
    assert small == pytest.approx(prof.motor.l_q_h, rel=0.1)  # the nominal value at small current
    for q in (5.0, 10.0, 15.0):
        lq = dev.plant_flux(0.0, q)["l_qq_h"]
        assert lq < 0.8 * small and lq == pytest.approx(dev.plant_flux(0.0, -q)["l_qq_h"], rel=1e-6)
    assert dev.plant_flux(0.0, 0.0)["psi_d_wb"] == pytest.approx(prof.motor.psi_f_wb, rel=1e-6)
    # the measured SEW map as it is: the plant reproduces its nodes
    sew = load_flux_map(str(ROOT / "profiles" / "maps" / "sew-cm3c80s.csv"))
    sprof = load_profile(str(ROOT / "profiles" / "sew-cm3c80s.yaml"))
    sdev = EmulatedDevice(emulator_settings(sprof.motor, sprof.rig))
    for i_d, i_q in ((0, 0), (-5, 8), (-10, -4), (1, 15)):
        pd, pq = sew.node(i_d, i_q)
        f = sdev.plant_flux(float(i_d), float(i_q))
        assert (f["psi_d_wb"], f["psi_q_wb"]) == pytest.approx((pd, pq), abs=1e-9)


def test_thermal_drift_moves_r_and_psi_f_by_the_coefficients(ideal, tmp_path):
    rig = write_rig(
        tmp_path,
        "th",
        "  thermal: {temp_ambient_c: 25, temp_winding_c: 100, temp_magnet_c: 80,\n"
        "            c_winding_j_k: 5.0, c_magnet_j_k: 20.0, r_wa_k_w: 2.0,\n"
        "            r_wm_k_w: 2.0, r_ma_k_w: 2.0}\n",
    )
    prof, _log, truth = run(rig, tmp_path / "th.mcap")
    m = prof.motor
    r_exp = m.r_s_ohm * (1 + 0.00393 * (truth["temp_winding_c"] - 25.0))
    psi_exp = m.psi_f_wb * (1 - 0.001 * (truth["temp_magnet_c"] - 25.0))
    assert np.allclose(truth["r_s_ohm"], r_exp, rtol=1e-12)
    assert np.allclose(truth["psi_f_wb"], psi_exp, rtol=1e-12)
    assert truth["temp_winding_c"][0] == pytest.approx(100.0, abs=1.0)
    # it cools towards the ambient and the copper loss heats it: both visible in a second
    assert truth["temp_winding_c"][-1] < 95.0 and truth["temp_magnet_c"][-1] < 79.0
    # the firmware-side signature: the back-EMF u_q / w_e (no load, i_d ~ 0) falls with psi_f
    win = (0.25, 0.45)
    tt, ti = tru(truth, win), tru(ideal[2], win)
    we = 600 / 60 * 2 * math.pi * m.pole_pairs
    emf = np.mean(tt["u_q_v"] - tt["r_s_ohm"] * tt["i_q_a"]) / we
    emf_i = np.mean(ti["u_q_v"] - m.r_s_ohm * ti["i_q_a"]) / we
    assert emf / emf_i == pytest.approx(tt["psi_f_wb"].mean() / m.psi_f_wb, abs=0.01)
    assert emf / emf_i < 0.96


def test_encoder_offset_rotates_the_measured_dq_frame(ideal, tmp_path):
    delta = 0.15
    rig = write_rig(tmp_path, "enc", f"  encoder: {{lines: 2500, offset_e_rad: {delta}}}\n")
    _, log, truth = run(rig, tmp_path / "enc.mcap")
    tl, tt = tel(log), tru(truth)
    # the firmware's angle leads the rotor's by the offset
    th_true = np.interp(tl["t_s"], tt["t_s"], np.unwrap(tt["theta_e_rad"]))
    err = np.angle(np.exp(1j * (tl["theta_e_rad"] - th_true)))
    assert np.median(err) == pytest.approx(delta, abs=0.03)
    # so the measured current vector is the true one turned back by the offset
    meas = complex(tl["i_d_a"].mean(), tl["i_q_a"].mean())
    true = complex(tt["i_d_a"].mean(), tt["i_q_a"].mean())
    assert np.angle(true / meas) == pytest.approx(delta, abs=0.03)
    assert abs(meas) == pytest.approx(abs(true), rel=0.03)


def test_dc_link_ripple_is_what_the_firmware_measures(ideal, tmp_path):
    rig = write_rig(
        tmp_path,
        "dc",
        "  dc_link: {r_source_ohm: 0.5, c_dc_f: 6.8e-4, rectifier: true, grid_hz: 50}\n",
    )
    _, log, truth = run(rig, tmp_path / "dc.mcap")
    tt = tru(truth)
    v = tt["v_dc_v"]
    assert v.max() <= 540.0 + 1e-9 and np.ptp(v) > 1.0
    # six-pulse ripple: 300 Hz
    x = v - v.mean()
    f = np.fft.rfftfreq(len(x), np.median(np.diff(tt["t_s"])))
    assert abs(f[np.argmax(np.abs(np.fft.rfft(x)))] - 300.0) < 5.0
    cap = log.topic("/pmsm/capture")
    assert np.ptp(cap["v_dc_v"]) > 0.5  # the firmware sees the ripple
    assert np.ptp(tru(ideal[2])["v_dc_v"]) == 0.0


def test_iron_loss_power_and_drag(ideal, tmp_path):
    r_fe = 200.0
    rig = write_rig(tmp_path, "fe", f"  iron_loss: {{r_fe_ohm: {r_fe}}}\n")
    prof, _log, truth = run(rig, tmp_path / "fe.mcap")
    win = (0.25, 0.45)  # no load, 600 r/min
    tt, ti = tru(truth, win), tru(ideal[2], win)
    m = prof.motor
    we = 600 / 60 * 2 * math.pi * m.pole_pairs
    assert tt["p_fe_w"].mean() == pytest.approx(1.5 * (we * m.psi_f_wb) ** 2 / r_fe, rel=0.05)
    # the current loop supplies the loss: extra q current for the drag torque P_fe / w_m
    diq = tt["i_q_a"].mean() - ti["i_q_a"].mean()
    t_fe = tt["p_fe_w"].mean() / (we / m.pole_pairs)
    assert diq == pytest.approx(t_fe / (1.5 * m.pole_pairs * m.psi_f_wb), rel=0.25)


def test_cogging_torque_has_its_period_and_size(tmp_path):
    rig = write_rig(
        tmp_path, "cog", "  cogging: {amplitude_nm: 0.2, periods_per_rev: 72, phase_rad: 0.0}\n"
    )
    prof = load_profile(str(STEADY), rig_override=str(rig))
    dev = EmulatedDevice(emulator_settings(prof.motor, prof.rig))
    th = np.linspace(0, 2 * math.pi, 721)[:-1]
    t = np.array([dev.plant_flux(0.0, 0.0, float(x))["torque_nm"] for x in th])
    assert t.max() == pytest.approx(0.2, rel=1e-3) and t.min() == pytest.approx(-0.2, rel=1e-3)
    assert harmonic(
        t, th, 72 // prof.motor.pole_pairs, window=(-1, 1), t=np.zeros_like(th)
    ) == pytest.approx(0.2, rel=1e-3)


def test_lab_typical_runs_the_short_profile(tmp_path):
    _prof, log, truth = run(RIGS / "lab-typical.yaml", tmp_path / "lab.mcap")
    on = (1 << len(EFFECT_BITS)) - 1 - (1 << EFFECT_BITS["motor_deviation"])
    assert set(log.topic("/sim/truth")["effects"].tolist()) == {on}
    tl = tel(log)
    assert abs(np.mean(tl["speed_rpm"]) - 600.0) < 6.0
    assert truth["temp_winding_c"][0] == pytest.approx(60.0, abs=0.1)


def _small_current(dev: EmulatedDevice) -> tuple[float, float, float]:
    """psi_f, L_d, L_q of the plant at small current (flux at 0 A; chords over +-0.5 A)."""
    f0 = dev.plant_flux(0.0, 0.0)
    fd = dev.plant_flux(0.5, 0.0)
    fq = dev.plant_flux(0.0, 0.5)
    return f0["psi_d_wb"], (fd["psi_d_wb"] - f0["psi_d_wb"]) / 0.5, fq["psi_q_wb"] / 0.5


@pytest.mark.parametrize("plant", ["linear", "flux map"])
def test_motor_deviation_moves_the_plant_not_the_firmware(tmp_path, plant):
    dev_yaml = (
        "  motor_deviation: {r_s_factor: 1.05, l_d_factor: 1.08, l_q_factor: 0.95, "
        "psi_f_factor: 0.97}\n"
    )
    sat = "  saturation: {map: %s}\n" % (ROOT / "profiles" / "maps" / "paper-a-ipmsm.csv")
    base_yaml = sat if plant == "flux map" else "  dead_time: {enabled: false}\n"
    base = load_profile(str(STEADY), rig_override=str(write_rig(tmp_path, "b", base_yaml)))
    off = load_profile(
        str(STEADY), rig_override=str(write_rig(tmp_path, "d", base_yaml + dev_yaml))
    )
    s0 = emulator_settings(base.motor, base.rig)
    s1 = emulator_settings(off.motor, off.rig)
    assert s1["r_s_ohm"] == pytest.approx(1.05 * s0["r_s_ohm"], rel=1e-12)
    psi0, ld0, lq0 = _small_current(EmulatedDevice(s0))
    psi1, ld1, lq1 = _small_current(EmulatedDevice(s1))
    assert psi1 / psi0 == pytest.approx(0.97, rel=2e-3)
    assert ld1 / ld0 == pytest.approx(1.08, rel=2e-3)
    assert lq1 / lq0 == pytest.approx(0.95, rel=2e-3)
    # the firmware is told the motor file's values, whatever the plant
    assert off.motor.l_d_h == base.motor.l_d_h and off.motor.psi_f_wb == base.motor.psi_f_wb
    assert off.rig.effects_mask == base.rig.effects_mask | (1 << EFFECT_BITS["motor_deviation"])
