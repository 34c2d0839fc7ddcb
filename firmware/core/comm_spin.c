/* Commissioning step: psi_f by a short spin (docs/commissioning.md). Field-oriented current
 * control on the commissioned encoder angle, i_d = 0, a gentle speed loop, two speeds (30 % and
 * 100 % of spin_rpm): at each, averaged over whole electrical turns,
 *   psi_f = (u_q + distortion_q - R i_q - omega_e L_d i_d) / omega_e,
 * the distortion from the measured inverter model. Then back to standstill. */
#include "comm.h"
#include "transforms.h"

#include <math.h>

#define SP_RAMP_RPM_S  2000.0f
#define SP_BW_RAD_S    40.0f
#define SP_SETTLE_S    0.3f
#define SP_MEAS_S      0.2f
#define SP_STUCK_S     1.5f
#define SP_HOLD_S      0.05f
#define SP_STILL_RPM   3.0f
#define SP_START_RPM   10.0f
#define SP_RPM_PER_RAD 9.549296585513720f
#define SP_AGREE       0.05f

static void finish(comm_t *c)
{
    const float p1 = c->psi_pt[0], p2 = c->psi_pt[1];
    c->res.value[0] = p2;
    c->res.value[1] = p1;
    c->res.value[2] = p2;
    c->res.spread[0] = 0.5f * fabsf(p2 - p1);
    c->res.ref[0] = c->cfg.spin_rpm;
    if (!(p2 >= 0.3f * c->cfg.motor.psi_f_wb && p2 <= 3.0f * c->cfg.motor.psi_f_wb)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_IMPLAUSIBLE);
        return;
    }
    if (!(fabsf(p2 - p1) <= SP_AGREE * p2)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_NOT_REPEATABLE);
        return;
    }
    comm_finish_step(c);
}

void comm_spin_step(comm_t *c, const comm_in_t *in, comm_out_t *out)
{
    const fw_motor_t *m = &c->cfg.motor;
    const float kt = 1.5f * (float)m->pole_pairs * m->psi_f_wb;
    const float kp = m->j_kgm2 * SP_BW_RAD_S / kt, ki = kp * SP_BW_RAD_S / 4.0f;
    const float speed_rpm = in->omega_e_rad_s / (float)m->pole_pairs * SP_RPM_PER_RAD;
    const float target =
        c->phase == 0u ? 0.3f * c->cfg.spin_rpm : (c->phase == 1u ? c->cfg.spin_rpm : 0.0f);
    const float i_lim = 0.5f * c->cfg.i_test_a;
    const float step = SP_RAMP_RPM_S * c->cfg.ts_s;
    float e, iq_ref, id, iq, i3[3], dd, dq;
    bool braking;

    c->i_max_step = 1.5f * c->cfg.i_test_a + 1.0f;
    if (comm_over_current(c)) {
        return;
    }
    if (!(fabsf(speed_rpm) <= 1.3f * c->cfg.spin_rpm + 50.0f)) {
        comm_fail(c, PROTO_COMMISSION_FAIL_OVER_SPEED);
        return;
    }
    /* the spin starts from rest: a rotor still turning from the previous step (a standstill
     * step's test currents can leave it coasting) is first braked by the speed loop at 0 r/min
     * (for at most SP_STUCK_S), and the direction check waits for the ramp */
    braking = c->phase == 0u && c->spd_ref_rpm == 0.0f && !(fabsf(speed_rpm) < SP_START_RPM) &&
              (float)c->t < comm_dt(c, SP_STUCK_S);
    if (c->phase < 2u && c->t_total > 0u && c->spd_ref_rpm > 30.0f && speed_rpm < -30.0f) {
        comm_fail(c, PROTO_COMMISSION_FAIL_WRONG_DIRECTION);
        return;
    }
    /* reference ramp and the speed PI (mechanical rad/s -> i_q) */
    if (braking) {
        /* hold the reference at 0 */
    } else if (c->spd_ref_rpm < target) {
        c->spd_ref_rpm = c->spd_ref_rpm + step < target ? c->spd_ref_rpm + step : target;
    } else if (c->spd_ref_rpm > target) {
        c->spd_ref_rpm = c->spd_ref_rpm - step > target ? c->spd_ref_rpm - step : target;
    }
    e = (c->spd_ref_rpm - speed_rpm) / SP_RPM_PER_RAD;
    c->spd_int += ki * c->cfg.ts_s * e;
    c->spd_int = c->spd_int > i_lim ? i_lim : (c->spd_int < -i_lim ? -i_lim : c->spd_int);
    iq_ref = kp * e + c->spd_int;
    iq_ref = iq_ref > i_lim ? i_lim : (iq_ref < -i_lim ? -i_lim : iq_ref);
    c->adv_rad = 1.5f * in->omega_e_rad_s * c->cfg.ts_s;
    comm_current(c, c->c_rot, c->s_rot, 0.0f, iq_ref, &id, &iq, out);
    out->speed_ref_rpm = c->spd_ref_rpm;

    if (c->phase == 2u) { /* back to standstill */
        if (c->spd_ref_rpm == 0.0f && fabsf(speed_rpm) < SP_STILL_RPM) {
            c->acc_n++;
        } else {
            c->acc_n = 0u;
        }
        if ((float)c->acc_n >= comm_dt(c, SP_HOLD_S)) {
            c->adv_rad = 0.0f;
            finish(c);
        }
        return;
    }
    if (c->spd_ref_rpm != target || !comm_elapsed(c, SP_SETTLE_S)) {
        if (c->spd_ref_rpm != target && !braking) {
            c->t = 0u;
        }
        return;
    }
    if (c->acc_n == 0u && !(fabsf(speed_rpm) >= 0.8f * target)) {
        if ((float)c->t > comm_dt(c, SP_STUCK_S)) {
            comm_fail(c, PROTO_COMMISSION_FAIL_ROTOR_STUCK);
        }
        return;
    }
    i3[0] = c->ia;
    i3[1] = c->ib;
    i3[2] = c->ic;
    comm_inv_dist(c, i3, c->c_rot, c->s_rot, &dd, &dq);
    c->acc[0] += c->u_q + dq;
    c->acc[1] += iq;
    c->acc[2] += id;
    c->acc[3] += in->omega_e_rad_s;
    c->acc_n++;
    if ((float)c->acc_n < comm_dt(c, SP_MEAS_S)) {
        return;
    }
    {
        const float n = (float)c->acc_n, w = c->acc[3] / n;
        c->psi_pt[c->phase] =
            (c->acc[0] / n - c->r_ohm * c->acc[1] / n - w * c->l_d_h * c->acc[2] / n) /
            (fabsf(w) > 1.0f ? w : 1.0f);
    }
    comm_next_phase(c);
}
