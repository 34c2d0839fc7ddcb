/* The plant's measurement chain: phase-current sensors (delay, gain, offset, noise, ADC
 * quantisation), the DC-link voltage and the incremental encoder. */
#include "plant_internal.h"

/* ------------------------------------------------------------------ sensors (effect seam) */

/* one phase-current channel: true current -> + Gaussian noise -> ADC quantisation (mid-tread).
 * Offsets, gain errors, range clipping, filtering belong here. */
PL_INLINE double sensor_current(plant_t *p, double i)
{
    double v = i;
    if (p->cfg.i_noise_a > 0.0) {
        v += p->cfg.i_noise_a * rng_gauss(&p->rng);
    }
    if (p->inv_lsb >
        0.0) { /* round to nearest (even) by the 1.5 * 2^52 trick: branch-free, exact */
        const double q = v * p->inv_lsb;
        v = ((q + 6755399441055744.0) - 6755399441055744.0) * p->cfg.adc_lsb_a;
    }
    return v;
}

/* the measured phase currents with the sensor effects: sample delay (linear interpolation between
 * the true currents at the period boundaries; exact for a piecewise-linear current), gain, offset,
 * then noise and quantisation */
static void sample_general(plant_t *p, fw_meas_t *m)
{
    double i3[3];
    int n;
    if (p->delay_n >= 0) {
        const double *a = p->hist_i[(p->hist_pos - (uint32_t)p->delay_n) & (PLANT_DELAY_RING - 1u)];
        const double *b =
            p->hist_i[(p->hist_pos - (uint32_t)p->delay_n - 1u) & (PLANT_DELAY_RING - 1u)];
        for (n = 0; n < 3; n++) {
            i3[n] = a[n] + p->delay_f * (b[n] - a[n]);
        }
    } else {
        phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
    }
    for (n = 0; n < 3; n++) {
        i3[n] = p->cfg.i_gain[n] * i3[n] + p->cfg.i_offset_a[n];
    }
    m->i_a_a = (float)sensor_current(p, i3[0]);
    m->i_b_a = (float)sensor_current(p, i3[1]);
    m->i_c_a = (float)sensor_current(p, i3[2]);
}

/* incremental encoder: floor of the mechanical angle (plus offset) in counts, wrapped to [0, N) */
PL_INLINE uint32_t sensor_encoder(const plant_t *p)
{
    double a = p->theta_m_rad + p->enc_off_w;
    uint32_t c;
    if (a >= PL_TWO_PI) {
        a -= PL_TWO_PI;
    }
    c = (uint32_t)(a * p->enc_scale);
    if (c >= p->cfg.enc_counts) {
        c -= p->cfg.enc_counts;
    }
    return c;
}

void plant_sample(plant_t *p, fw_meas_t *m)
{
    if (p->sens_general) {
        sample_general(p, m);
    } else {
        double i3[3];
        phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
        m->i_a_a = (float)sensor_current(p, i3[0]);
        m->i_b_a = (float)sensor_current(p, i3[1]);
        m->i_c_a = (float)sensor_current(p, i3[2]);
    }
    m->v_dc_v = (float)p->v_dc_v;
    m->enc_count = sensor_encoder(p);
}
