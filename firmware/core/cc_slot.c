/* The current-control slot (cc_slot.h): dispatch to the occupant, the MPCC or FOC. */
#include "cc_slot.h"

bool cc_kind_known(uint16_t kind)
{
    return kind == CC_KIND_MPCC || kind == CC_KIND_FOC;
}

bool cc_uses_duties(const cc_t *c)
{
    return c->kind == CC_KIND_FOC;
}

void cc_init(cc_t *c, const cc_cfg_t *cfg)
{
    c->kind = cc_kind_known(cfg->kind) ? cfg->kind : CC_KIND_MPCC;
    if (c->kind == CC_KIND_FOC) {
        foc_init(&c->u.foc, &cfg->foc);
    } else {
        mpcc_init(&c->u.mpcc, &cfg->mpcc);
    }
}

static void step_mpcc(mpcc_t *m, const cc_in_t *in, cc_out_t *out)
{
    mpcc_in_t mi;
    mpcc_out_t mo;
    mi.i_d_a = in->i_d_a;
    mi.i_q_a = in->i_q_a;
    mi.i_d_ref_a = in->i_d_ref_a;
    mi.i_q_ref_a = in->i_q_ref_a;
    mi.theta_e_rad = in->theta_e_rad;
    mi.omega_e_rad_s = in->omega_e_rad_s;
    mi.v_dc_v = in->v_dc_v;
    mi.r_s_ohm = in->pred.r_s_ohm;
    mi.l_d_h = in->pred.l_d_h;
    mi.l_q_h = in->pred.l_q_h;
    mi.psi_f_wb = in->pred.psi_f_wb;
    mpcc_step_cs(m, &mi, in->cos_theta, in->sin_theta, &mo);
    out->mode = CC_OUT_STATES;
    out->s_a = mo.s_a;
    out->s_b = mo.s_b;
    out->s_c = mo.s_c;
    out->duty_a = (float)mo.s_a;
    out->duty_b = (float)mo.s_b;
    out->duty_c = (float)mo.s_c;
    out->u_d_v = mo.u_d_v;
    out->u_q_v = mo.u_q_v;
    out->u_d_avg_v = mo.u_d_avg_v;
    out->u_q_avg_v = mo.u_q_avg_v;
    out->i_d_pred_a = mo.i_d_k1_a;
    out->i_q_pred_a = mo.i_q_k1_a;
    /* back to the stationary frame at the angle the MPCC used (new output; no effect on control) */
    out->u_alpha_v = in->cos_theta * mo.u_d_v - in->sin_theta * mo.u_q_v;
    out->u_beta_v = in->sin_theta * mo.u_d_v + in->cos_theta * mo.u_q_v;
}

static void step_foc(foc_t *f, const cc_in_t *in, cc_out_t *out)
{
    foc_in_t fi;
    foc_out_t fo;
    fi.i_d_a = in->i_d_a;
    fi.i_q_a = in->i_q_a;
    fi.i_d_ref_a = in->i_d_ref_a;
    fi.i_q_ref_a = in->i_q_ref_a;
    fi.cos_theta = in->cos_theta;
    fi.sin_theta = in->sin_theta;
    fi.omega_e_rad_s = in->omega_e_rad_s;
    fi.v_dc_v = in->v_dc_v;
    fi.r_s_ohm = in->pred.r_s_ohm;
    fi.l_d_h = in->pred.l_d_h;
    fi.l_q_h = in->pred.l_q_h;
    fi.psi_f_wb = in->pred.psi_f_wb;
    foc_step(f, &fi, &fo);
    out->mode = CC_OUT_DUTIES;
    out->duty_a = fo.duty_a;
    out->duty_b = fo.duty_b;
    out->duty_c = fo.duty_c;
    out->s_a = (uint16_t)(fo.duty_a > 0.5f);
    out->s_b = (uint16_t)(fo.duty_b > 0.5f);
    out->s_c = (uint16_t)(fo.duty_c > 0.5f);
    out->u_d_v = fo.u_d_v;
    out->u_q_v = fo.u_q_v;
    out->u_d_avg_v = fo.u_d_avg_v;
    out->u_q_avg_v = fo.u_q_avg_v;
    out->u_alpha_v = fo.u_alpha_v;
    out->u_beta_v = fo.u_beta_v;
    out->i_d_pred_a = fo.i_d_k1_a;
    out->i_q_pred_a = fo.i_q_k1_a;
}

void cc_step(cc_t *c, const cc_in_t *in, cc_out_t *out)
{
    switch (c->kind) {
    case CC_KIND_FOC:
        step_foc(&c->u.foc, in, out);
        break;
    case CC_KIND_MPCC:
    default:
        step_mpcc(&c->u.mpcc, in, out);
        break;
    }
}

void cc_reset(cc_t *c)
{
    if (c->kind == CC_KIND_FOC) {
        foc_reset(&c->u.foc);
    } else {
        mpcc_reset(&c->u.mpcc);
    }
}

uint16_t cc_segment_kind(uint16_t seg_flags, uint16_t fallback)
{
    if ((seg_flags & PROTO_SEGMENT_FLAG_CC_FOC) != 0u) {
        return CC_KIND_FOC;
    }
    if ((seg_flags & PROTO_SEGMENT_FLAG_CC_MPCC) != 0u) {
        return CC_KIND_MPCC;
    }
    return fallback;
}

void cc_hand_over(cc_t *c, const cc_cfg_t *cfg, uint16_t kind, const cc_in_t *in, float u_d_mean_v,
                  float u_q_mean_v)
{
    float u_al, u_be;
    if (kind == c->kind || !cc_kind_known(kind)) {
        return;
    }
    /* what the present occupant applies during the running period (before the union changes) */
    if (c->kind == CC_KIND_FOC) {
        u_al = c->u.foc.u_al_next;
        u_be = c->u.foc.u_be_next;
    } else {
        mpcc_vector(c->u.mpcc.sw_prev, &u_al, &u_be);
        u_al *= in->v_dc_v;
        u_be *= in->v_dc_v;
    }
    c->kind = kind;
    if (kind == CC_KIND_FOC) {
        foc_init(&c->u.foc, &cfg->foc);
        /* the PI's output is kp e + x + ff with ff the decoupling at the present currents:
         * with e about zero, x = mean voltage - ff continues the MPCC's mean voltage */
        const float w = in->omega_e_rad_s;
        const float ff_d = -w * in->pred.l_q_h * in->i_q_a;
        const float ff_q = w * (in->pred.l_d_h * in->i_d_a + in->pred.psi_f_wb);
        foc_take_over(&c->u.foc, u_al, u_be, u_d_mean_v - ff_d, u_q_mean_v - ff_q);
    } else {
        mpcc_init(&c->u.mpcc, &cfg->mpcc);
        mpcc_take_over(&c->u.mpcc, u_al, u_be);
    }
}

uint16_t cc_applied_code(const cc_t *c)
{
    return c->kind == CC_KIND_MPCC ? c->u.mpcc.sw_prev : 0u;
}
