/* Hybrid angle source (docs/sensorless.md, "Hybrid"): the ripple PLL at low speed, the MRAS
 * above. The MRAS's weight w in the angle ramps between 0 and 1 at a bounded rate:
 *     theta = theta_pll + w wrap(theta_mras - theta_pll),   omega = omega_pll
 * so a handover never steps the angle: the output moves by at most the estimators' difference
 * times ts/blend_s per period, and the difference itself is small when both are locked (a
 * larger one is a disagreement, below). The speed is the PLL's at every speed: the MRAS's (its
 * adaptation's output) jumps by hundreds of r/min when the current steps on a saturating motor
 * (docs/sensorless.md). Hysteresis: w heads for 1 once |speed| exceeds mras_on_rpm and for 0
 * once it falls below pll_on_rpm (< mras_on_rpm); in between it keeps its direction.
 *
 * Supervision (loss of lock): above pll_on_rpm both estimators are valid, and a difference of
 * more than disagree_rad for longer than disagree_s is a loss of lock; the PLL's confidence
 * below conf_min for longer than lost_s while it carries the output (w < 1) is another. The MRAS
 * counts only while it reports lock, agrees with the PLL within disagree_rad and has not jumped
 * against it since the last period (by disagree_rad or more): until then the output stays the
 * PLL's, and when it stops counting while it has weight, w heads for 0 with the difference held
 * at its last counted value (an MRAS losing its track jumps by up to pi, sometimes a period
 * before it reports the loss). The PLL's pole comes
 * from the start-up polarity test; a difference near pi is a disagreement like any other (turning
 * the PLL on the MRAS's word would trust the less robust estimator with the pole). */
#ifndef HYBRID_H
#define HYBRID_H

#include <stdint.h>
#include <stdbool.h>

#define HYB_LOCK_OK       0u
#define HYB_LOCK_DISAGREE 1u /* the two estimators disagree */
#define HYB_LOCK_LOW_CONF 2u /* the PLL's confidence is too low */

typedef struct {
    float ts_s;
    uint16_t pole_pairs;
    float pll_on_rpm, mras_on_rpm; /* hysteresis band, r/min (mechanical) */
    float blend_s;                 /* time of a full handover */
    float disagree_rad, disagree_s;
    float conf_min, lost_s;
} hyb_cfg_t;

typedef struct {
    float theta_pll_rad, omega_pll_rad_s, conf_pll;
    float theta_mras_rad, omega_mras_rad_s;
    bool mras_locked; /* the MRAS reports lock (converged, within its speed range) */
} hyb_in_t;

typedef struct {
    float theta_e_rad, omega_e_rad_s;
    float w_mras;   /* weight of the MRAS in the output, [0, 1] */
    float diff_rad; /* wrap(theta_mras - theta_pll) */
    uint16_t lock;  /* HYB_LOCK_* (latched) */
} hyb_out_t;

typedef struct {
    hyb_cfg_t cfg;
    float w, dw, rpm_per_rad_s;
    float diff_held_rad; /* wrap(theta_mras - theta_pll) when the MRAS last counted */
    float raw_prev_rad;  /* wrap(theta_mras - theta_pll) of the last period */
    bool to_mras;
    uint32_t n_dis, n_conf, n_dis_max, n_conf_max;
    uint16_t lock;
} hyb_t;

void hyb_init(hyb_t *h, const hyb_cfg_t *cfg);
void hyb_step(hyb_t *h, const hyb_in_t *in, hyb_out_t *out);

#endif
