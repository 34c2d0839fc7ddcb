/* The sensorless estimator's configuration (docs/sensorless.md): from the host's
 * config_sensorless and gamma_node frames, or, when the host sent none, from the motor and the
 * firmware's defaults (nominal inductances, the physics' polarity sign). Part of the fw object. */
#include "fw_internal.h"

#include <string.h>

void fw_snl_config(const fw_t *f, snl_cfg_t *sc)
{
    const proto_config_ctrl_t *c = &f->ctrl;
    const proto_config_sensorless_t *m = &f->snl_msg;
    const bool have = f->have_snl;
    memset(sc, 0, sizeof(*sc));
    sc->mode = c->angle_src == PROTO_ANGLE_SRC_HYBRID ? SNL_MODE_HYBRID : SNL_MODE_PLL;
    sc->pll.ts_s = c->ts_s;
    sc->pll.pole_pairs = f->motor.pole_pairs;
    sc->pll.r_s_ohm = f->motor.r_s_ohm;
    sc->pll.l_d_h = f->motor.l_d_h;
    sc->pll.l_q_h = f->motor.l_q_h;
    sc->pll.psi_f_wb = f->motor.psi_f_wb;
    sc->pll.j_kgm2 = f->motor.j_kgm2;
    sc->pll.bw_rad_s = c->est_bw_rad_s;
    sc->pll.torque_ff = true;
    sc->pll.excite_a = have ? m->pll_excite_a : 0.0f;
    rerr_gamma_linear(&sc->pll.gamma, f->motor.l_d_h, f->motor.l_q_h);
    if (have && m->gam_nd >= 2u && m->gam_nq >= 2u &&
        (uint32_t)f->gamma_nodes == (uint32_t)m->gam_nd * (uint32_t)m->gam_nq) {
        sc->pll.gamma.tab = &f->gamma_tab;
    }
    sc->pol.ts_s = c->ts_s;
    sc->pol.i_pulse_a = have ? m->pol_i_pulse_a : 0.5f * f->motor.i_max_a;
    sc->pol.settle_s = FW_POL_SETTLE_S;
    sc->pol.pulse_s = FW_POL_PULSE_S;
    sc->pol.release_s = FW_POL_RELEASE_S;
    sc->pol.asym_expected = have ? m->pol_asym_expected : FW_POL_ASYM_DEFAULT;
    sc->pol.asym_min = have ? m->pol_asym_min : FW_POL_ASYM_MIN_DEFAULT;
    sc->pol.conf_min = FW_POL_CONF_MIN;
    sc->hyb.ts_s = c->ts_s;
    sc->hyb.pole_pairs = f->motor.pole_pairs;
    sc->hyb.pll_on_rpm = have ? m->hyb_pll_on_rpm : 150.0f;
    sc->hyb.mras_on_rpm = have ? m->hyb_mras_on_rpm : 250.0f;
    sc->hyb.blend_s = have ? m->hyb_blend_s : 0.02f;
    sc->hyb.disagree_rad = have ? m->lock_disagree_rad : 0.3f;
    sc->hyb.disagree_s = have ? m->lock_disagree_s : 0.02f;
    sc->hyb.conf_min = have ? m->lock_conf_min : 0.5f;
    sc->hyb.lost_s = have ? m->lock_lost_s : 0.05f;
}
