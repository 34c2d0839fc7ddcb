/* Current-frequency start (if_start.h). */
#include "if_start.h"
#include "fw_types.h"

#include <math.h>
#include <string.h>

static float wrap_pi(float x)
{
    while (x > FW_PI_F) {
        x -= FW_TWO_PI_F;
    }
    while (x < -FW_PI_F) {
        x += FW_TWO_PI_F;
    }
    return x;
}

void ifs_init(ifs_t *s, const ifs_cfg_t *cfg)
{
    memset(s, 0, sizeof(*s));
    s->cfg = *cfg;
    s->phase = (cfg->i_a > 0.0f && cfg->accel_rad_s2 > 0.0f && cfg->handover_rad_s > 0.0f)
                   ? IFS_ALIGN
                   : IFS_DISABLED;
    s->theta_rad = wrap_pi(cfg->theta0_rad);
}

/* Toward the reference at the configured acceleration. */
static void ramp_speed(ifs_t *s, float target)
{
    const float dw = s->cfg.accel_rad_s2 * s->cfg.ts_s;
    if (s->omega_rad_s < target - dw) {
        s->omega_rad_s += dw;
    } else if (s->omega_rad_s > target + dw) {
        s->omega_rad_s -= dw;
    } else {
        s->omega_rad_s = target;
    }
}

void ifs_step(ifs_t *s, const ifs_in_t *in, ifs_out_t *out)
{
    const float ts = s->cfg.ts_s;
    memset(out, 0, sizeof(*out));
    out->theta_rad = in->theta_est_rad;
    out->omega_rad_s = in->omega_est_rad_s;
    s->t_s += ts;
    switch (s->phase) {
    case IFS_ALIGN:
        out->open_loop = true;
        out->hold_refs = true;
        out->i_d_inject_a = s->cfg.i_a * (s->t_s < s->cfg.align_s ? s->t_s / s->cfg.align_s : 1.0f);
        out->theta_rad = s->theta_rad;
        out->omega_rad_s = 0.0f;
        if (s->t_s >= 1.5f * s->cfg.align_s) { /* ramped, then held half as long */
            s->phase = IFS_RAMP;
            s->t_s = 0.0f;
        }
        break;
    case IFS_RAMP: {
        const bool at_speed = fabsf(s->omega_rad_s) >= s->cfg.handover_rad_s;
        const float delta = wrap_pi(s->theta_rad - in->theta_est_rad);
        ramp_speed(s, in->omega_ref_rad_s);
        s->theta_rad = wrap_pi(s->theta_rad + s->omega_rad_s * ts);
        out->open_loop = true;
        out->hold_refs = true;
        out->i_d_inject_a = s->cfg.i_a;
        out->theta_rad = s->theta_rad;
        out->omega_rad_s = s->omega_rad_s;
        if (!at_speed) {
            s->t_s = 0.0f; /* the timeout counts at handover speed only */
            s->settled_s = 0.0f;
            break;
        }
        s->settled_s =
            (in->est_locked && fabsf(delta) < s->cfg.max_delta_rad) ? s->settled_s + ts : 0.0f;
        if (s->settled_s >= s->cfg.settle_s) {
            s->i_d_left_a = s->cfg.i_a * cosf(delta);
            s->i_q_hold_a = s->cfg.i_a * sinf(delta);
            s->phase = IFS_DECAY;
            s->t_s = 0.0f;
            out->open_loop = false; /* this period already on the estimator's angle, the speed
                                       loop held once more at i_q_hold_a: it starts there */
            out->theta_rad = in->theta_est_rad;
            out->omega_rad_s = in->omega_est_rad_s;
            out->i_q_hold_a = s->i_q_hold_a;
            out->i_d_inject_a = s->i_d_left_a;
            out->handed_over_now = true;
        } else if (s->t_s >= s->cfg.timeout_s) {
            s->phase = IFS_FAILED;
        }
        break;
    }
    case IFS_DECAY:
        out->i_d_inject_a = s->i_d_left_a * (1.0f - s->t_s / s->cfg.decay_s);
        if (s->t_s >= s->cfg.decay_s) {
            out->i_d_inject_a = 0.0f;
            s->phase = IFS_DONE;
        }
        break;
    case IFS_FAILED: /* keep the open-loop current until the lock supervision stops the drive:
                        the estimator's angle is not to be trusted */
        s->theta_rad = wrap_pi(s->theta_rad + s->omega_rad_s * ts);
        out->open_loop = true;
        out->hold_refs = true;
        out->i_d_inject_a = s->cfg.i_a;
        out->theta_rad = s->theta_rad;
        out->omega_rad_s = s->omega_rad_s;
        out->failed = true;
        break;
    default:
        break;
    }
}
