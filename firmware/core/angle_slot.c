/* The angle slot (angle_slot.h): dispatch to the occupant: the encoder, the MRAS, the ripple PLL
 * or the hybrid of both estimators. */
#include "angle_slot.h"
#include "fw_types.h"

#include <string.h>

#define ANGLE_RPM_PER_RAD_S 9.549296585513720f

bool angle_src_known(uint16_t src)
{
    return src == ANGLE_SRC_ENCODER || src == ANGLE_SRC_MRAS || src == ANGLE_SRC_RIPPLE_PLL ||
           src == ANGLE_SRC_HYBRID;
}

bool angle_src_is_estimator(uint16_t src)
{
    return src != ANGLE_SRC_ENCODER;
}

void angle_init(angle_t *a, const angle_cfg_t *cfg)
{
    a->cfg = *cfg;
    if (!angle_src_known(cfg->src)) {
        a->cfg.src = ANGLE_SRC_ENCODER;
    }
    memset(&a->last, 0, sizeof(a->last));
    if ((a->cfg.src == ANGLE_SRC_RIPPLE_PLL || a->cfg.src == ANGLE_SRC_HYBRID) &&
        cfg->snl == NULL) {
        a->cfg.src = ANGLE_SRC_ENCODER;
    }
    if (a->cfg.src == ANGLE_SRC_RIPPLE_PLL || a->cfg.src == ANGLE_SRC_HYBRID) {
        snl_init(&a->u.sl.snl, cfg->snl);
        rpll_reset(&a->u.sl.snl.pll, cfg->theta0_rad, 0.0f);
    }
    if (a->cfg.src == ANGLE_SRC_MRAS || a->cfg.src == ANGLE_SRC_HYBRID) {
        mras_cfg_t mc;
        mc.ts_s = cfg->ts_s;
        mc.bw_rad_s = cfg->bw_rad_s;
        mc.min_speed_rad_s = cfg->min_speed_rpm * (float)cfg->pole_pairs / ANGLE_RPM_PER_RAD_S;
        mc.max_speed_rad_s = cfg->max_speed_rpm * (float)cfg->pole_pairs / ANGLE_RPM_PER_RAD_S;
        mc.theta0_rad = cfg->theta0_rad;
        mc.r_s_ohm = cfg->r_s_ohm;
        mc.l_d_h = cfg->l_d_h;
        mc.l_q_h = cfg->l_q_h;
        mc.psi_f_wb = cfg->psi_f_wb;
        /* the hybrid's MRAS runs without the torque feed-forward (paper B's law): the handover
         * was tuned on it; docs/sensorless.md */
        mc.j_kgm2 = a->cfg.src == ANGLE_SRC_HYBRID ? 0.0f : cfg->j_kgm2;
        mc.pole_pairs = cfg->pole_pairs;
        mras_init(a->cfg.src == ANGLE_SRC_HYBRID ? &a->u.sl.mras : &a->u.mras, &mc);
    }
    {
        ifs_cfg_t ic = cfg->ifs;
        ic.ts_s = cfg->ts_s;
        ic.theta0_rad = cfg->theta0_rad;
        if (a->cfg.src != ANGLE_SRC_MRAS) {
            ic.i_a = 0.0f; /* only the MRAS starts open loop */
        }
        ifs_init(&a->ifs, &ic);
        a->if_failed_told = false;
    }
}

/* The encoder: its raw-count angle and its observer's speed. */
void angle_encoder_out(const angle_in_t *in, angle_out_t *out)
{
    if (in->enc == NULL) {
        memset(out, 0, sizeof(*out));
        out->valid = false;
        return;
    }
    out->theta_e_rad = in->enc->theta_e_rad;
    out->omega_e_rad_s = in->enc->omega_e_rad_s;
    out->omega_m_rad_s = in->enc->omega_m_rad_s;
    out->speed_rpm = in->enc->speed_rpm;
    out->valid = true;
    out->locked = true;
    out->confidence = 1.0f;
    out->err_rad = 0.0f;
}

static void step_mras(angle_t *a, const angle_in_t *in, angle_out_t *out)
{
    mras_in_t mi;
    mras_out_t mo;
    const float p = a->cfg.pole_pairs > 0u ? (float)a->cfg.pole_pairs : 1.0f;
    mi.i_alpha_a = in->i_alpha_a;
    mi.i_beta_a = in->i_beta_a;
    mi.u_alpha_v = in->u_alpha_prev_v;
    mi.u_beta_v = in->u_beta_prev_v;
    mras_step(&a->u.mras, &mi, &mo);
    out->hold_refs = false;
    out->i_d_inject_a = 0.0f;
    out->i_q_hold_a = 0.0f;
    out->open_loop = false;
    out->pol_result_now = 0u;
    out->if_event_now = 0u;
    out->theta_e_rad = mo.theta_e_rad;
    out->omega_e_rad_s = mo.omega_e_rad_s;
    out->omega_m_rad_s = mo.omega_e_rad_s / p;
    out->speed_rpm = out->omega_m_rad_s * ANGLE_RPM_PER_RAD_S;
    out->valid = true;
    out->locked = mo.locked;
    out->confidence = mo.confidence;
    out->err_rad = mo.eps_rad;
    if (a->ifs.phase != IFS_DISABLED && a->ifs.phase != IFS_DONE) {
        ifs_in_t ii;
        ifs_out_t io;
        ii.omega_ref_rad_s = in->omega_ref_e_rad_s;
        ii.theta_est_rad = mo.theta_e_rad;
        ii.omega_est_rad_s = mo.omega_e_rad_s;
        ii.est_locked = mo.locked;
        ifs_step(&a->ifs, &ii, &io);
        out->theta_e_rad = io.theta_rad < 0.0f ? io.theta_rad + FW_TWO_PI_F : io.theta_rad;
        out->omega_e_rad_s = io.omega_rad_s;
        out->omega_m_rad_s = io.omega_rad_s / p;
        out->speed_rpm = out->omega_m_rad_s * ANGLE_RPM_PER_RAD_S;
        out->hold_refs = io.hold_refs;
        out->i_q_hold_a = io.i_q_hold_a;
        out->i_d_inject_a = io.i_d_inject_a;
        out->open_loop = io.open_loop;
        if (io.open_loop) {
            out->locked = true; /* nothing to lose yet; a start that fails is a loss of lock */
        }
        if (io.handed_over_now) {
            out->if_event_now = PROTO_EVENT_IF_HANDOVER;
        }
        if (io.failed) {
            out->locked = false;
            if (!a->if_failed_told) {
                a->if_failed_told = true;
                out->if_event_now = PROTO_EVENT_IF_FAILED;
            }
        }
    }
}

/* The ripple PLL (with the polarity test at start), alone or blended with the MRAS. */
static void step_sensorless(angle_t *a, const angle_in_t *in, angle_out_t *out)
{
    snl_in_t si;
    snl_out_t so;
    const float p = a->cfg.pole_pairs > 0u ? (float)a->cfg.pole_pairs : 1.0f;
    memset(&si, 0, sizeof(si));
    si.i_alpha_a = in->i_alpha_a;
    si.i_beta_a = in->i_beta_a;
    si.u_alpha_prev_v = in->u_alpha_prev_v;
    si.u_beta_prev_v = in->u_beta_prev_v;
    si.u_valid = true;
    if (a->cfg.src == ANGLE_SRC_HYBRID) {
        mras_in_t mi;
        mras_out_t mo;
        mi.i_alpha_a = in->i_alpha_a;
        mi.i_beta_a = in->i_beta_a;
        mi.u_alpha_v = in->u_alpha_prev_v;
        mi.u_beta_v = in->u_beta_prev_v;
        mras_step(&a->u.sl.mras, &mi, &mo);
        si.theta_mras_rad = mo.theta_e_rad;
        si.omega_mras_rad_s = mo.omega_e_rad_s;
        si.mras_locked = mo.locked;
    }
    snl_step(&a->u.sl.snl, &si, &so);
    memset(out, 0, sizeof(*out));
    out->theta_e_rad = so.theta_e_rad;
    out->omega_e_rad_s = so.omega_e_rad_s;
    out->omega_m_rad_s = so.omega_e_rad_s / p;
    out->speed_rpm = out->omega_m_rad_s * ANGLE_RPM_PER_RAD_S;
    out->valid = true;
    /* the polarity test holds the references while it runs: locked until it has failed */
    out->locked = so.lock == SNL_LOCK_OK;
    out->confidence = so.conf < 0.0f ? 0.0f : (so.conf > 1.0f ? 1.0f : so.conf);
    out->err_rad = so.err_rad;
    out->hold_refs = so.startup;
    out->i_d_inject_a = so.i_d_inject_a;
    out->pol_result_now = so.pol_done_now ? so.pol_result : 0u;
    out->pol_asym = so.pol_asym;
}

void angle_step(angle_t *a, const angle_in_t *in, angle_out_t *out)
{
    switch (a->cfg.src) {
    case ANGLE_SRC_RIPPLE_PLL:
    case ANGLE_SRC_HYBRID:
        step_sensorless(a, in, out);
        break;
    case ANGLE_SRC_MRAS:
        step_mras(a, in, out);
        break;
    case ANGLE_SRC_ENCODER:
    default:
        angle_encoder_out(in, out);
        break;
    }
    a->last = *out;
}
