/* IPMSM + two-level inverter + sensors + load: the emulator's plant. See plant.h and docs/plant.md.
 *
 * Structure (the seams for the rig effects), one file per concern:
 *   mag_eval()      (plant_mag.h, plant_map.c) magnetics: currents (and angle) -> flux linkages, inverse incremental inductances,
 *                   d(psi)/d(theta), extra torque. The one place for saturation, flux harmonics, cogging.
 *   deriv()         (plant_integ.h) the dq voltage equations and the mechanics, evaluated at one RK4 stage.
 *   leg_dist()      (plant_inverter.c) inverter distortion voltage per leg (dead time, device drop).
 *   sensor_*()      (plant_sensors.c) phase-current ADC, DC-link voltage, encoder: offsets, gains,
 *                   noise, quantisation.
 *   advance_on()    (plant_integ.c) RK4 over one period with a known stationary-frame (or rotor-frame) voltage.
 *   advance_off()   (plant_inverter.c) PWM off: diode bridge with current-zero events.
 *   thermal network and DC link (plant_thermal.c).
 * This file: the configuration, the initial state, the truth and the parameter steps. */
#include "plant_integ.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

double plant_sigmoid(double x)
{
    return sigm(x);
}

/* ------------------------------------------------------------------ API */

void plant_cfg_default(plant_cfg_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->r_s_ohm = 0.9;
    cfg->l_d_h = 5e-3;
    cfg->l_q_h = 12e-3;
    cfg->psi_f_wb = 0.18;
    cfg->pole_pairs = 4;
    cfg->j_kgm2 = 0.0036;
    cfg->b_visc_nms = 0.0;
    cfg->t_coulomb_nm = 0.0;
    cfg->v_dc_v = 540.0;
    cfg->dead_time_s = 0.0;
    cfg->v_drop_v = 0.0;
    cfg->i_dt_a = 0.5;
    cfg->i_noise_a = 0.0;
    cfg->adc_lsb_a = 0.0;
    cfg->enc_counts = 10000u;
    cfg->enc_offset_m_rad = 0.0;
    cfg->ts_s = 50e-6;
    cfg->substeps = 1;
    cfg->seed = 1u;
    cfg->temp_ambient_c = 25.0;
    /* rig effects, all off; the thermal numbers are those of docs/rigs.md's thermal effect */
    cfg->map = NULL;
    cfg->thermal_on = 0;
    cfg->temp_ref_c = 25.0;
    cfg->temp_winding0_c = 25.0;
    cfg->temp_magnet0_c = 25.0;
    cfg->alpha_r_per_k = 0.00393;
    cfg->alpha_psi_per_k = -0.001;
    cfg->c_winding_j_k = 1500.0;
    cfg->c_magnet_j_k = 600.0;
    cfg->r_wa_k_w = 0.4;
    cfg->r_wm_k_w = 0.5;
    cfg->r_ma_k_w = 1.0;
    cfg->r_fe_heat_ohm = 0.0;
    cfg->psi5_rel = 0.0;
    cfg->psi7_rel = 0.0;
    cfg->cog_nm = 0.0;
    cfg->cog_order_e = 6;
    cfg->cog_phase_rad = 0.0;
    cfg->i_offset_a[0] = cfg->i_offset_a[1] = cfg->i_offset_a[2] = 0.0;
    cfg->i_gain[0] = cfg->i_gain[1] = cfg->i_gain[2] = 1.0;
    cfg->sample_delay_s = 0.0;
    cfg->pwm_delay_periods = 0;
    cfg->dc_on = 0;
    cfg->dc_r_src_ohm = 0.5;
    cfg->dc_c_f = 1e-3;
    cfg->dc_rectifier = 1;
    cfg->dc_grid_hz = 50.0;
    cfg->r_fe_ohm = 0.0;
}

const char *plant_cfg_check(const plant_cfg_t *cfg)
{
    if (!(cfg->r_s_ohm >= 0.0))
        return "r_s_ohm must be >= 0";
    if (!(cfg->l_d_h > 0.0))
        return "l_d_h must be > 0";
    if (!(cfg->l_q_h > 0.0))
        return "l_q_h must be > 0";
    if (!(cfg->psi_f_wb >= 0.0))
        return "psi_f_wb must be >= 0";
    if (cfg->pole_pairs < 1)
        return "pole_pairs must be >= 1";
    if (!(cfg->j_kgm2 > 0.0))
        return "j_kgm2 must be > 0";
    if (!(cfg->b_visc_nms >= 0.0))
        return "b_visc_nms must be >= 0";
    if (!(cfg->t_coulomb_nm >= 0.0))
        return "t_coulomb_nm must be >= 0";
    if (!(cfg->v_dc_v >= 0.0))
        return "v_dc_v must be >= 0";
    if (!(cfg->dead_time_s >= 0.0 && cfg->dead_time_s < cfg->ts_s))
        return "dead_time_s must be in [0, ts_s)";
    if (!(cfg->v_drop_v >= 0.0))
        return "v_drop_v must be >= 0";
    if (!(cfg->i_noise_a >= 0.0))
        return "i_noise_a must be >= 0";
    if (!(cfg->adc_lsb_a >= 0.0))
        return "adc_lsb_a must be >= 0";
    if (cfg->enc_counts < 1u)
        return "enc_counts must be >= 1";
    if (!(cfg->ts_s > 0.0))
        return "ts_s must be > 0";
    if (cfg->substeps < 1)
        return "substeps must be >= 1";
    if (cfg->map != NULL && (cfg->map->nd < 2 || cfg->map->nq < 2))
        return "map is not built (plant_map_build)";
    if (cfg->thermal_on) {
        if (!(cfg->c_winding_j_k > 0.0) || !(cfg->c_magnet_j_k > 0.0))
            return "thermal capacities must be > 0";
        if (!(cfg->r_wa_k_w > 0.0) || !(cfg->r_wm_k_w > 0.0) || !(cfg->r_ma_k_w > 0.0))
            return "thermal resistances must be > 0";
        if (!(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_winding_j_k * cfg->r_wm_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_magnet_j_k * cfg->r_wm_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_winding_j_k * cfg->r_wa_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_magnet_j_k * cfg->r_ma_k_w))
            return "thermal time constants must exceed 5 thermal steps (16 ts_s each)";
    }
    if (!(cfg->r_fe_heat_ohm >= 0.0))
        return "r_fe_heat_ohm must be >= 0";
    if (!(fabs(cfg->psi5_rel) < 1.0) || !(fabs(cfg->psi7_rel) < 1.0))
        return "flux harmonics must be < 1";
    if (cfg->cog_nm != 0.0 && (cfg->cog_order_e < 1 || cfg->cog_order_e > 1000))
        return "cog_order_e must be in [1, 1000]";
    if (!(fabs(cfg->i_gain[0]) < 10.0) || !(fabs(cfg->i_gain[1]) < 10.0) ||
        !(fabs(cfg->i_gain[2]) < 10.0))
        return "i_gain must be finite";
    if (!(fabs(cfg->i_offset_a[0]) < 1e6) || !(fabs(cfg->i_offset_a[1]) < 1e6) ||
        !(fabs(cfg->i_offset_a[2]) < 1e6))
        return "i_offset_a must be finite";
    if (!(cfg->sample_delay_s >= 0.0 &&
          cfg->sample_delay_s <= (double)(PLANT_DELAY_RING - 3) * cfg->ts_s))
        return "sample_delay_s must be in [0, 29 ts_s]";
    if (cfg->pwm_delay_periods < 0 || cfg->pwm_delay_periods > PLANT_DELAY_RING - 1)
        return "pwm_delay_periods must be in [0, 31]";
    if (cfg->dc_on) {
        if (!(cfg->dc_r_src_ohm > 0.0))
            return "dc_r_src_ohm must be > 0";
        if (!(cfg->dc_c_f > 0.0))
            return "dc_c_f must be > 0";
        if (!(cfg->dc_grid_hz >= 0.0))
            return "dc_grid_hz must be >= 0";
    }
    if (!(cfg->r_fe_ohm >= 0.0))
        return "r_fe_ohm must be >= 0";
    return NULL;
}

void plant_init(plant_t *p, const plant_cfg_t *cfg)
{
    memset(p, 0, sizeof *p);
    p->cfg = *cfg;
    if (p->cfg.substeps < 1) {
        p->cfg.substeps = 1;
    }
    if (p->cfg.pole_pairs < 1) {
        p->cfg.pole_pairs = 1;
    }
    if (p->cfg.enc_counts < 1u) {
        p->cfg.enc_counts = 1u;
    }
    p->r_s_ohm = cfg->r_s_ohm;
    p->l_d_h = cfg->l_d_h;
    p->l_q_h = cfg->l_q_h;
    p->psi_f_wb = cfg->psi_f_wb;
    p->v_dc_v = cfg->v_dc_v;
    p->temp_winding_c = cfg->temp_ambient_c;
    p->temp_magnet_c = cfg->temp_ambient_c;
    p->inv_l_d = 1.0 / cfg->l_d_h;
    p->inv_l_q = 1.0 / cfg->l_q_h;
    p->inv_j = 1.0 / cfg->j_kgm2;
    p->inv_i_dt = cfg->i_dt_a > 0.0 ? 1.0 / cfg->i_dt_a : 0.0;
    p->dist_on = p->inv_i_dt > 0.0 && (cfg->v_drop_v > 0.0 || cfg->dead_time_s > 0.0);
    p->inv_lsb = cfg->adc_lsb_a > 0.0 ? 1.0 / cfg->adc_lsb_a : 0.0;
    p->enc_scale = (double)p->cfg.enc_counts / PL_TWO_PI;
    p->enc_off_w = wrap_2pi(fmod(cfg->enc_offset_m_rad, PL_TWO_PI));
    p->h_s = cfg->ts_s / (double)p->cfg.substeps;
    p->inv_ts = 1.0 / cfg->ts_s;
    p->cos_e = 1.0;
    p->sin_e = 0.0;
    p->pwm_prev = false;
    rng_seed(&p->rng, cfg->seed);
    /* rig effects */
    p->psi_f_ref_wb = cfg->map != NULL ? cfg->map->psi_f_wb : cfg->psi_f_wb;
    p->psi_f_wb = p->psi_f_ref_wb;
    p->psi_shift_wb = 0.0;
    if (cfg->thermal_on) {
        p->temp_winding_c = cfg->temp_winding0_c;
        p->temp_magnet_c = cfg->temp_magnet0_c;
        pl_thermal_params(p);
    }
    p->inv_r_fe = cfg->r_fe_ohm > 0.0 ? 1.0 / cfg->r_fe_ohm : 0.0;
    p->mag_general = cfg->map != NULL || cfg->psi5_rel != 0.0 || cfg->psi7_rel != 0.0 ||
                     cfg->cog_nm != 0.0 || p->inv_r_fe > 0.0;
    p->cog_c = cos(cfg->cog_phase_rad);
    p->cog_s = sin(cfg->cog_phase_rad);
    if (cfg->sample_delay_s > 0.0) {
        const double nd = floor(cfg->sample_delay_s * p->inv_ts + 1e-9);
        p->delay_n = (int)nd;
        p->delay_f = cfg->sample_delay_s * p->inv_ts - nd;
        if (p->delay_f < 0.0) {
            p->delay_f = 0.0;
        }
        pl_hist_fill(p);
    } else {
        p->delay_n = -1;
        p->delay_f = 0.0;
    }
    p->sens_general = p->delay_n >= 0 || cfg->i_offset_a[0] != 0.0 || cfg->i_offset_a[1] != 0.0 ||
                      cfg->i_offset_a[2] != 0.0 || cfg->i_gain[0] != 1.0 || cfg->i_gain[1] != 1.0 ||
                      cfg->i_gain[2] != 1.0;
    p->fifo_pos = 0u;
    p->v_src_v = cfg->v_dc_v;
    p->grid_c = 1.0;
    p->grid_s = 0.0;
    p->grid_dc = cos(PL_TWO_PI * cfg->dc_grid_hz * cfg->ts_s);
    p->grid_ds = sin(PL_TWO_PI * cfg->dc_grid_hz * cfg->ts_s);
    p->i_dc_a = 0.0;
}

void plant_set_mech(plant_t *p, double theta_m_rad, double omega_m_rad_s, bool hold_speed)
{
    const double the = (double)p->cfg.pole_pairs * wrap_2pi(fmod(theta_m_rad, PL_TWO_PI));
    p->theta_m_rad = wrap_2pi(fmod(theta_m_rad, PL_TWO_PI));
    p->omega_m_rad_s = omega_m_rad_s;
    p->hold_speed = hold_speed;
    p->cos_e = cos(the);
    p->sin_e = sin(the);
    if (p->delay_n >= 0) {
        pl_hist_fill(p);
    }
}

void plant_set_currents(plant_t *p, double i_d_a, double i_q_a)
{
    p->i_d_a = i_d_a;
    p->i_q_a = i_q_a;
    p->diodes_valid =
        false; /* re-derive the diode states from the current signs if PWM is off next */
    if (p->delay_n >= 0) {
        pl_hist_fill(p);
    }
}

/* below this current the secant inductance is its limit, the incremental one */
#define PL_SECANT_MIN_A 0.05

/* The apparent L_d on a flux map, as steady-state equations identify it (docs/identification.md,
 * "The truth the estimators are scored against"): they fit psi_d = psi_f,app + L_d,app i_d to
 * window means, so the truth is the least-squares line through 1 ms means of (i_d, psi_d) over
 * about the last 0.1 s (an excitation's levels, the ripple averaged as a window averages it).
 * psi_d is the map's (plus the thermal shift): flux harmonics are no inductance.
 * L_q likewise: the steady-state d equation gives L_q,app = psi_q / i_q at the operating point,
 * and psi_q follows the i_d excitation (cross-saturation), so the truth is the ratio of the means
 * of psi_q and i_q over the same memory (the excitation's levels averaged as the fit averages
 * them). Both fluxes are those of the magnetising current: with iron loss, the current the
 * firmware measures is i_m + i_fe (mag_at). */
#define PL_APP_BLOCK_S  1e-3
#define PL_APP_MEMORY   100.0 /* blocks */
#define PL_APP_MIN_SD_A 0.25  /* spread of the block means below which the line is undefined */

void pl_apparent_ld_step(plant_t *p)
{
    double psi_d, psi_q, l[4];
    const int n_blk = (int)(PL_APP_BLOCK_S * p->inv_ts + 0.5);
    map_eval(p->cfg.map, p->i_d_a, p->i_q_a, &psi_d, &psi_q, l);
    p->map_memo_ok = 1; /* the map at these currents, for the next period's first stage */
    p->map_memo_id = p->i_d_a;
    p->map_memo_iq = p->i_q_a;
    p->map_memo_pd = psi_d;
    p->map_memo_pq = psi_q;
    memcpy(p->map_memo_l, l, sizeof l);
    if (p->inv_r_fe > 0.0) { /* the flux of the magnetising current (mag_at), without harmonics */
        const double we = (double)p->cfg.pole_pairs * p->omega_m_rad_s;
        const double ifd = -we * psi_q * p->inv_r_fe;
        const double ifq = we * (psi_d + p->psi_shift_wb) * p->inv_r_fe;
        psi_d -= l[0] * ifd + l[1] * ifq;
        psi_q -= l[2] * ifd + l[3] * ifq;
    }
    p->app_blk_i += p->i_d_a;
    p->app_blk_psi += psi_d + p->psi_shift_wb;
    p->app_blk_iq += p->i_q_a;
    p->app_blk_psiq += psi_q;
    if (++p->app_n >= (n_blk > 1 ? n_blk : 1)) {
        const double k = 1.0 - 1.0 / PL_APP_MEMORY;
        const double i = p->app_blk_i / (double)p->app_n, psi = p->app_blk_psi / (double)p->app_n;
        const double iq = p->app_blk_iq / (double)p->app_n;
        const double psiq = p->app_blk_psiq / (double)p->app_n;
        p->app_sq = k * p->app_sq + iq;
        p->app_spq = k * p->app_spq + psiq;
        p->app_blk_iq = 0.0;
        p->app_blk_psiq = 0.0;
        p->app_s0 = k * p->app_s0 + 1.0;
        p->app_si = k * p->app_si + i;
        p->app_sp = k * p->app_sp + psi;
        p->app_sii = k * p->app_sii + i * i;
        p->app_sip = k * p->app_sip + i * psi;
        p->app_n = 0;
        p->app_blk_i = 0.0;
        p->app_blk_psi = 0.0;
    }
}

/* L_q,app of the block means, or 0 while their i_q is too small to define it */
static double apparent_lq(const plant_t *p)
{
    if (!(p->app_s0 > 0.0) || !(fabs(p->app_sq) >= p->app_s0 * PL_SECANT_MIN_A)) {
        return 0.0;
    }
    return p->app_spq / p->app_sq;
}

/* the slope of that line, or 0 when the block means do not spread enough to define it */
static double apparent_ld(const plant_t *p)
{
    double mi, var;
    if (!(p->app_s0 > 0.0)) {
        return 0.0;
    }
    mi = p->app_si / p->app_s0;
    var = p->app_sii / p->app_s0 - mi * mi;
    if (!(var >= PL_APP_MIN_SD_A * PL_APP_MIN_SD_A)) {
        return 0.0;
    }
    return (p->app_sip / p->app_s0 - mi * p->app_sp / p->app_s0) / var;
}

void plant_truth(const plant_t *p, plant_truth_t *t)
{
    plant_mag_t m;
    double i3[3], idm, iqm;
    const double pp = (double)p->cfg.pole_pairs;
    mag_at(p, p->mag_general ? 1 : 0, p->i_d_a, p->i_q_a, pp * p->omega_m_rad_s, p->cos_e, p->sin_e,
           &m, &idm, &iqm);
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
    t->i_d_a = p->i_d_a;
    t->i_q_a = p->i_q_a;
    t->theta_m_rad = p->theta_m_rad;
    t->theta_e_rad = wrap_2pi(fmod(pp * p->theta_m_rad, PL_TWO_PI));
    t->omega_m_rad_s = p->omega_m_rad_s;
    t->speed_rpm = p->omega_m_rad_s * (30.0 / PL_PI);
    t->torque_nm = torque_of(p, idm, iqm, &m) + cog_torque(p, p->cos_e, p->sin_e);
    t->u_d_v = p->u_d_avg_v;
    t->u_q_v = p->u_q_avg_v;
    t->r_s_ohm = p->r_s_ohm;
    t->l_d_h =
        m.l_dd; /* incremental inductances in force (the nominal ones for the linear machine) */
    t->l_q_h = m.l_qq;
    t->l_dq_h = m.l_dq;
    t->psi_d_wb = m.psi_d_wb;
    t->psi_q_wb = m.psi_q_wb;
    t->l_q_secant_h = fabs(p->i_q_a) >= PL_SECANT_MIN_A ? m.psi_q_wb / p->i_q_a : m.l_qq;
    t->l_d_secant_h = m.l_dd;
    if (fabs(p->i_d_a) >= PL_SECANT_MIN_A) {
        plant_mag_t m0, m1;
        mag_eval(p, p->mag_general ? 1 : 0, p->i_d_a, p->i_q_a, p->cos_e, p->sin_e, &m1);
        mag_eval(p, p->mag_general ? 1 : 0, 0.0, p->i_q_a, p->cos_e, p->sin_e, &m0);
        t->l_d_secant_h = (m1.psi_d_wb - m0.psi_d_wb) / p->i_d_a;
    }
    if (p->cfg.map != NULL) {
        const double l_app = apparent_ld(p), l_q_app = apparent_lq(p);
        if (l_app > 0.0) {
            t->l_d_secant_h = l_app;
        }
        if (l_q_app > 0.0) {
            t->l_q_secant_h = l_q_app;
        }
    }
    pl_losses(p, &t->p_cu_w, &t->p_fe_w);
    t->i_dc_a = p->i_dc_a;
    t->v_dist_v[0] = p->v_dist_v[0];
    t->v_dist_v[1] = p->v_dist_v[1];
    t->v_dist_v[2] = p->v_dist_v[2];
    t->psi_f_wb = p->psi_f_wb;
    t->temp_winding_c = p->temp_winding_c;
    t->temp_magnet_c = p->temp_magnet_c;
    t->t_s = (double)p->n_periods * p->cfg.ts_s;
    t->i_a_a = i3[0];
    t->i_b_a = i3[1];
    t->i_c_a = i3[2];
    t->omega_e_rad_s = pp * p->omega_m_rad_s;
    t->v_dc_v = p->v_dc_v;
    t->load_nm = p->load_nm;
}

void plant_set_param_scale(plant_t *p, const plant_cfg_t *base, double r_s_scale,
                           double psi_f_scale)
{
    const double r_new = base->r_s_ohm * r_s_scale;
    const double psi_old_scale = base->psi_f_wb > 0.0 ? p->cfg.psi_f_wb / base->psi_f_wb : 1.0;
    const double k_psi = psi_old_scale > 0.0 ? psi_f_scale / psi_old_scale : 1.0;
    const double psi_before = p->psi_f_wb;
    p->r_s_ohm = p->cfg.r_s_ohm > 0.0 ? p->r_s_ohm * (r_new / p->cfg.r_s_ohm) : r_new;
    p->cfg.r_s_ohm = r_new;
    p->cfg.psi_f_wb = base->psi_f_wb * psi_f_scale;
    p->psi_f_ref_wb *= k_psi;
    p->psi_f_wb *= k_psi;
    p->psi_shift_wb += p->psi_f_wb - psi_before;
}
