/* Encoder angle and speed observer. See enc_angle.h and docs/control.md. */
#include "enc_angle.h"

#include <math.h>
#include "transforms.h"

#define ENC_COUNTS_MAX 0x7FFFFFFFu
#define ENC_RPM_PER_RAD_S 9.54929658551372f

void enc_init(enc_t *e, const enc_cfg_t *cfg)
{
    float bw, k1, k2;
    e->cfg = *cfg;
    if (e->cfg.counts < 4u) {
        e->cfg.counts = 4u;
    }
    if (e->cfg.counts > ENC_COUNTS_MAX) {
        e->cfg.counts = ENC_COUNTS_MAX;
    }
    if (e->cfg.pole_pairs == 0u) {
        e->cfg.pole_pairs = 1u;
    }
    if (!(e->cfg.ts_s > 0.0f)) {
        e->cfg.ts_s = 50.0e-6f;
    }
    bw = e->cfg.bw_rad_s;
    if (!(bw > 0.0f)) {
        bw = ENC_BW_DEFAULT_RAD_S;
    }
    /* keep the discrete tracker well inside its stability region (k1 ts <= ~0.28) */
    if (bw * e->cfg.ts_s > 0.2f) {
        bw = 0.2f / e->cfg.ts_s;
    }
    e->cfg.bw_rad_s = bw;
    k1 = 2.0f * ENC_ZETA_F * bw;
    k2 = bw * bw;
    e->k1_ts = k1 * e->cfg.ts_s;
    e->k2_ts = k2 * e->cfg.ts_s;
    e->rad_per_count = FW_TWO_PI_F / (float)e->cfg.counts;
    enc_reset(e, 0u);
}

void enc_reset(enc_t *e, uint32_t count)
{
    e->n_obs = count % e->cfg.counts;
    e->f_obs = 0.0f;
    e->w_cps = 0.0f;
}

/* Move the observer's integer part by the whole counts in f_obs, leaving f_obs in [0, 1). */
static void carry(enc_t *e)
{
    const uint32_t n = e->cfg.counts;
    float fl;
    int32_t k;
    if (e->f_obs >= 0.0f && e->f_obs < 1.0f) {
        return;
    }
    fl = floorf(e->f_obs);
    if (!(fl > -2.0e9f && fl < 2.0e9f)) {   /* absurd (or NaN) state: restart at the integer part */
        e->f_obs = 0.0f;
        e->w_cps = 0.0f;
        return;
    }
    k = (int32_t)fl;
    e->f_obs -= fl;
    if (e->f_obs >= 1.0f) {   /* rounding */
        e->f_obs = 0.0f;
        k++;
    }
    k %= (int32_t)n;
    if (k < 0) {
        k += (int32_t)n;
    }
    e->n_obs = (e->n_obs + (uint32_t)k) % n;
}

void enc_step(enc_t *e, uint32_t count, enc_out_t *out)
{
    const uint32_t n = e->cfg.counts;
    const uint32_t p = e->cfg.pole_pairs;
    const uint32_t c = count % n;
    uint32_t diff;
    float err, theta_obs_counts;

    /* raw-count angles */
    out->theta_m_rad = (float)c * e->rad_per_count;
    if (n <= 0xFFFFFFFFu / p) {
        const uint32_t ce = (c * p) % n;   /* electrical position in counts, exact */
        out->theta_e_rad = tf_wrap_2pi((float)ce * e->rad_per_count + e->cfg.offset_rad);
    } else {
        out->theta_e_rad = tf_wrap_2pi((float)p * out->theta_m_rad + e->cfg.offset_rad);
    }

    /* observer: predict, innovation (wrapped), correct */
    e->f_obs += e->cfg.ts_s * e->w_cps;
    carry(e);
    diff = (c + n - e->n_obs) % n;   /* [0, n) */
    if (diff > n / 2u) {
        err = -(float)(n - diff) - e->f_obs;
    } else {
        err = (float)diff - e->f_obs;
    }
    e->f_obs += e->k1_ts * err;
    e->w_cps += e->k2_ts * err;
    carry(e);

    out->err_counts = err;
    out->omega_m_rad_s = e->w_cps * e->rad_per_count;
    out->omega_e_rad_s = (float)e->cfg.pole_pairs * out->omega_m_rad_s;
    out->speed_rpm = out->omega_m_rad_s * ENC_RPM_PER_RAD_S;
    if (n <= 0xFFFFFFFFu / p) {
        theta_obs_counts = (float)((e->n_obs * p) % n) + e->f_obs * (float)e->cfg.pole_pairs;
    } else {
        theta_obs_counts = ((float)e->n_obs + e->f_obs) * (float)e->cfg.pole_pairs;
    }
    out->theta_e_obs_rad = tf_wrap_2pi(theta_obs_counts * e->rad_per_count + e->cfg.offset_rad);
}
