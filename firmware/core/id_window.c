#include "id_window.h"

#include <math.h>

void idw_reset(idw_t *w)
{
    w->count = 0u;
    w->started = false;
    w->s_ud = w->s_uq = w->s_id = w->s_iq = w->s_w = w->s_wid = w->s_wiq = 0.0f;
    w->id0 = w->iq0 = w->w0 = w->wid0 = w->wiq0 = 0.0f;
    w->ang_rad = 0.0f;
    w->target_rad = 0.0f;
    w->th_prev = 0.0f;
}

#define IDW_PI         3.14159265f
#define IDW_SECTOR_RAD 1.04719755f /* 60 degrees electrical */

/* May the running window end at this sample? (idw_cfg_t.sector_sync) */
static bool window_ends(idw_t *w, float omega_e_rad_s)
{
    const float step = fabsf(omega_e_rad_s) * w->cfg.ts_s;
    const float ang = fabsf(w->ang_rad);
    if (w->count < w->cfg.n_periods) {
        return false;
    }
    if (!w->cfg.sector_sync || w->count >= (uint16_t)(IDW_SYNC_MAX * w->cfg.n_periods)) {
        return true;
    }
    if (!(w->target_rad > 0.0f)) {
        float k = ceilf(ang / IDW_SECTOR_RAD);
        w->target_rad = (k < 1.0f ? 1.0f : k) * IDW_SECTOR_RAD;
    }
    return ang + 0.5f * step >= w->target_rad;
}

void idw_init(idw_t *w, const idw_cfg_t *cfg)
{
    w->cfg = *cfg;
    if (w->cfg.n_periods < 2u) {
        w->cfg.n_periods = 2u;
    }
    if (!(w->cfg.ts_s > 0.0f)) {
        w->cfg.ts_s = 50e-6f;
    }
    idw_reset(w);
}

bool idw_step(idw_t *w, const idw_in_t *in, id_sample_t *out)
{
    bool ready = false;
    const float wid = in->omega_e_rad_s * in->i_d_a;
    const float wiq = in->omega_e_rad_s * in->i_q_a;
    if (w->started) { /* the angle step of the last period, wrapped to +-pi */
        float d = in->theta_e_rad - w->th_prev;
        d -= 2.0f * IDW_PI * floorf((d + IDW_PI) / (2.0f * IDW_PI));
        w->ang_rad += d;
    }
    w->th_prev = in->theta_e_rad;
    if (w->started && window_ends(w, in->omega_e_rad_s)) {
        const float n = (float)w->count;
        const float inv_n = 1.0f / n;
        const float t = n * w->cfg.ts_s;
        out->t_window_s = t;
        out->u_d_v = w->s_ud * inv_n;
        out->u_q_v = w->s_uq * inv_n;
        /* trapezoid: sum_{j=0}^{n-1} x_j + (x_n - x_0) / 2 */
        out->i_d_a = (w->s_id + 0.5f * (in->i_d_a - w->id0)) * inv_n;
        out->i_q_a = (w->s_iq + 0.5f * (in->i_q_a - w->iq0)) * inv_n;
        {
            const float w_est = (w->s_w + 0.5f * (in->omega_e_rad_s - w->w0)) * inv_n;
            const float dw = w->ang_rad / t - w_est; /* the speed estimate's lag */
            out->omega_e_rad_s = w_est + dw;
            out->w_i_d_a_rad_s = (w->s_wid + 0.5f * (wid - w->wid0)) * inv_n + dw * out->i_d_a;
            out->w_i_q_a_rad_s = (w->s_wiq + 0.5f * (wiq - w->wiq0)) * inv_n + dw * out->i_q_a;
        }
        out->di_d_a_s = (in->i_d_a - w->id0) / t;
        out->di_q_a_s = (in->i_q_a - w->iq0) / t;
        ready = true;
        w->count = 0u;
        w->s_ud = w->s_uq = w->s_id = w->s_iq = w->s_w = w->s_wid = w->s_wiq = 0.0f;
        w->ang_rad = 0.0f;
        w->target_rad = 0.0f;
    }
    if (w->count == 0u) {
        w->id0 = in->i_d_a;
        w->iq0 = in->i_q_a;
        w->w0 = in->omega_e_rad_s;
        w->wid0 = wid;
        w->wiq0 = wiq;
        w->started = true;
    }
    w->s_ud += in->u_d_v;
    w->s_uq += in->u_q_v;
    w->s_id += in->i_d_a;
    w->s_iq += in->i_q_a;
    w->s_w += in->omega_e_rad_s;
    w->s_wid += wid;
    w->s_wiq += wiq;
    w->count++;
    return ready;
}
