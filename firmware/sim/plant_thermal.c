/* The plant's thermal network (winding and magnet temperatures, the parameters that follow them,
 * copper and iron losses) and the DC link (source, rectifier, capacitor). */
#include "plant_integ.h"

#include <math.h>

/* copper and iron losses at the present state */
void pl_losses(const plant_t *p, double *p_cu, double *p_fe)
{
    const double r_fe_inv = p->inv_r_fe > 0.0
                                ? p->inv_r_fe
                                : (p->cfg.r_fe_heat_ohm > 0.0 ? 1.0 / p->cfg.r_fe_heat_ohm : 0.0);
    *p_cu = 1.5 * p->r_s_ohm * (p->i_d_a * p->i_d_a + p->i_q_a * p->i_q_a);
    *p_fe = 0.0;
    if (r_fe_inv > 0.0) {
        const double we = (double)p->cfg.pole_pairs * p->omega_m_rad_s;
        plant_mag_t m;
        double idm, iqm, ed, eq;
        mag_at(p, p->mag_general ? 1 : 0, p->i_d_a, p->i_q_a, we, p->cos_e, p->sin_e, &m, &idm,
               &iqm);
        ed = -we * (m.psi_q_wb - m.dpsi_d_dth_wb);
        eq = we * (m.psi_d_wb + m.dpsi_q_dth_wb);
        *p_fe = 1.5 * (ed * ed + eq * eq) * r_fe_inv;
    }
}

/* parameters that follow the temperatures */
void pl_thermal_params(plant_t *p)
{
    p->r_s_ohm =
        p->cfg.r_s_ohm * (1.0 + p->cfg.alpha_r_per_k * (p->temp_winding_c - p->cfg.temp_ref_c));
    p->psi_f_wb =
        p->psi_f_ref_wb * (1.0 + p->cfg.alpha_psi_per_k * (p->temp_magnet_c - p->cfg.temp_ref_c));
    p->psi_shift_wb = p->cfg.map != NULL ? p->psi_f_wb - p->cfg.map->psi_f_wb
                                         : 0.0; /* added to the map's psi_d */
}

/* two-node thermal network, explicit Euler every PLANT_THERMAL_DIV periods (time constants are seconds
 * to minutes) with the copper loss averaged over those periods and the iron loss at their end:
 * C_w dT_w/dt = P_cu + P_fe - (T_w - T_a)/R_wa - (T_w - T_m)/R_wm,  C_m dT_m/dt = (T_w - T_m)/R_wm - (T_m - T_a)/R_ma */
void pl_thermal_step(plant_t *p)
{
    const double dt = p->cfg.ts_s * (double)PLANT_THERMAL_DIV, ta = p->cfg.temp_ambient_c;
    const double tw = p->temp_winding_c, tm = p->temp_magnet_c;
    const double q_wm = (tw - tm) / p->cfg.r_wm_k_w;
    double p_cu_now;
    pl_losses(p, &p_cu_now, &p->p_fe_w);
    p->p_cu_w = p->th_acc_w * (1.0 / (double)PLANT_THERMAL_DIV);
    p->th_acc_w = 0.0;
    p->th_n = 0;
    p->temp_winding_c = tw + dt * (p->p_cu_w + p->p_fe_w - (tw - ta) / p->cfg.r_wa_k_w - q_wm) /
                                 p->cfg.c_winding_j_k;
    p->temp_magnet_c = tm + dt * (q_wm - (tm - ta) / p->cfg.r_ma_k_w) / p->cfg.c_magnet_j_k;
    pl_thermal_params(p);
}

/* DC link over the last period: C dv/dt = i_src - i_dc, i_src = (v_s - v)/R_src while the source
 * conducts (a diode rectifier only forwards), v_s the six-pulse rectified grid (line peak = v_src) or
 * a DC source; implicit Euler (R_src C may be a few periods). i_dc from the switch states (or duties)
 * and the mean of the phase currents at the period's start and end; PWM off: the upper diodes of the
 * phases with negative current feed the link. */
void pl_dc_link_step(plant_t *p, const double d[3], bool pwm_on, const double i0[3])
{
    double i1[3], idc = 0.0, vs = p->v_src_v, vnc;
    const double dt = p->cfg.ts_s, g = 1.0 / p->cfg.dc_r_src_ohm, inv_c = 1.0 / p->cfg.dc_c_f;
    int n;
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i1);
    for (n = 0; n < 3; n++) {
        const double im = 0.5 * (i0[n] + i1[n]);
        idc += pwm_on ? d[n] * im : (im < 0.0 ? im : 0.0);
    }
    p->i_dc_a = idc;
    if (p->cfg.dc_rectifier) {
        double c = p->grid_c * p->grid_dc - p->grid_s * p->grid_ds,
               s = p->grid_s * p->grid_dc + p->grid_c * p->grid_ds;
        const double r = 1.5 - 0.5 * (c * c + s * s);
        double a0, a1, a2, mx;
        c *= r;
        s *= r;
        p->grid_c = c;
        p->grid_s = s;
        /* the largest of the six line-to-line voltages: max |cos(th - k pi/3)|, k = 0, 1, 2 */
        a0 = fabs(c);
        a1 = fabs(0.5 * c + PL_SQRT3_2 * s);
        a2 = fabs(0.5 * c - PL_SQRT3_2 * s);
        mx = a0 > a1 ? a0 : a1;
        mx = mx > a2 ? mx : a2;
        vs *= mx;
    }
    vnc = p->v_dc_v - dt * inv_c * idc; /* source not conducting */
    if (p->cfg.dc_rectifier && vnc >= vs) {
        p->v_dc_v = vnc;
    } else {
        const double a = dt * g * inv_c;
        p->v_dc_v = (vnc + a * vs) / (1.0 + a);
    }
    if (p->v_dc_v < 0.0) {
        p->v_dc_v = 0.0;
    }
}
