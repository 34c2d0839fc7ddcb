/* Encoder angle and speed observer. See enc_angle.h and docs/control.md.
 * C28x note: the F28335 has no 32-bit integer divider (a % is a ~100-cycle library call) and
 * floorf is a library call too, so the per-period path uses neither: counts arrive in range,
 * modulo reductions are conditional subtractions bounded by the pole-pair count. */
#include "enc_angle.h"

#include <math.h>
#include "transforms.h"

#define ENC_COUNTS_MAX    0x7FFFFFFFu
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
    e->cfg.offset_e_rad =
        (e->cfg.offset_e_rad == e->cfg.offset_e_rad) ? tf_wrap_2pi(e->cfg.offset_e_rad) : 0.0f;
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
    /* exact integer electrical position needs counts * pole_pairs to fit 32 bits */
    e->int_elec = (e->cfg.counts <= 0xFFFFFFFFu / (uint32_t)e->cfg.pole_pairs);
    enc_reset(e, 0u);
}

void enc_reset(enc_t *e, uint32_t count)
{
    e->n_obs = count % e->cfg.counts;
    e->f_obs = 0.0f;
    e->w_cps = 0.0f;
}

/* (c * p) mod n for c < n without a division: at most p - 1 subtractions. */
static uint32_t mul_mod(uint32_t c, uint32_t p, uint32_t n)
{
    uint32_t x = c * p;
    while (x >= n) {
        x -= n;
    }
    return x;
}

/* x in [0, 4 pi) -> [0, 2 pi) */
static float wrap_once(float x)
{
    if (x >= FW_TWO_PI_F) {
        x -= FW_TWO_PI_F;
    }
    if (x >= FW_TWO_PI_F || x < 0.0f) {
        x = tf_wrap_2pi(x); /* rounding corner: the general (library) wrap */
    }
    return x;
}

/* Move the observer's integer part by the whole counts in f_obs, leaving f_obs in [0, 1). */
static void carry(enc_t *e)
{
    const uint32_t n = e->cfg.counts;
    int32_t k;
    if (e->f_obs >= 0.0f && e->f_obs < 1.0f) {
        return;
    }
    if (!(e->f_obs > -1.0e9f && e->f_obs < 1.0e9f)) { /* absurd (or NaN) state: restart here */
        e->f_obs = 0.0f;
        e->w_cps = 0.0f;
        return;
    }
    k = (int32_t)e->f_obs; /* truncation toward zero */
    if ((float)k > e->f_obs) {
        k--; /* floor */
    }
    e->f_obs -= (float)k;
    if (e->f_obs >= 1.0f) { /* rounding */
        e->f_obs -= 1.0f;
        k++;
    }
    if (e->f_obs < 0.0f) {
        e->f_obs = 0.0f;
    }
    if (k >= (int32_t)n || k <= -(int32_t)n) {
        k %= (int32_t)n; /* more than a turn per period: not a real speed */
    }
    if (k < 0) {
        const uint32_t d = (uint32_t)(-k);
        e->n_obs = (e->n_obs >= d) ? (e->n_obs - d) : (e->n_obs + n - d);
    } else {
        const uint32_t d = (uint32_t)k;
        e->n_obs = (e->n_obs >= n - d) ? (e->n_obs - (n - d)) : (e->n_obs + d);
    }
}

void enc_step(enc_t *e, uint32_t count, enc_out_t *out)
{
    const uint32_t n = e->cfg.counts;
    const uint32_t p = e->cfg.pole_pairs;
    const uint32_t c = (count < n) ? count : (count % n);
    uint32_t diff;
    float err, obs_counts;

    /* raw-count angles */
    out->theta_m_rad = (float)c * e->rad_per_count;
    if (e->int_elec) {
        out->theta_e_rad =
            wrap_once((float)mul_mod(c, p, n) * e->rad_per_count + e->cfg.offset_e_rad);
    } else {
        out->theta_e_rad = tf_wrap_2pi((float)p * out->theta_m_rad + e->cfg.offset_e_rad);
    }

    /* observer: predict, innovation (wrapped to +-n/2), correct */
    e->f_obs += e->cfg.ts_s * e->w_cps;
    carry(e);
    diff = (c >= e->n_obs) ? (c - e->n_obs) : (c + (n - e->n_obs)); /* [0, n) */
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
    if (e->int_elec) {
        obs_counts = (float)mul_mod(e->n_obs, p, n) + e->f_obs * (float)e->cfg.pole_pairs;
        out->theta_e_obs_rad = wrap_once(obs_counts * e->rad_per_count + e->cfg.offset_e_rad);
    } else {
        obs_counts = ((float)e->n_obs + e->f_obs) * (float)e->cfg.pole_pairs;
        out->theta_e_obs_rad = tf_wrap_2pi(obs_counts * e->rad_per_count + e->cfg.offset_e_rad);
    }
}
