/* The sensorless angle source as the angle slot sees it (docs/sensorless.md): the ripple PLL
 * (est_ripple_pll.h), the start-up polarity test (polarity.h) and, in hybrid mode, the blend with
 * the MRAS (hybrid.h); with the supervision that turns a loss of lock into a fault.
 *
 * Start: the PLL locks at rest (its own d-axis excitation when the controller's ripple is too
 * small), the polarity test pulses the d axis, and only then is the output valid; while the test
 * runs, `startup` asks the caller to hold the speed loop with i_q* = 0 and to add i_d_inject_a
 * to the d reference. A polarity that cannot be resolved, the PLL's confidence below conf_min for
 * longer than lost_s, or (hybrid) the estimators' disagreement is a loss of lock, latched. */
#ifndef SENSORLESS_H
#define SENSORLESS_H

#include <stdint.h>
#include <stdbool.h>

#include "est_ripple_pll.h"
#include "hybrid.h"
#include "polarity.h"

#define SNL_MODE_PLL    0u
#define SNL_MODE_HYBRID 1u

#define SNL_LOCK_OK       0u
#define SNL_LOCK_DISAGREE 1u /* hybrid: the PLL and the MRAS disagree */
#define SNL_LOCK_LOW_CONF 2u /* the PLL's confidence stayed low */
#define SNL_LOCK_POLARITY 3u /* polarity not resolved (a plant that does not saturate) */
#define SNL_LOCK_NO_START 4u /* the PLL did not lock at rest before the polarity test */

typedef struct {
    uint16_t mode; /* SNL_MODE_* */
    rpll_cfg_t pll;
    pol_cfg_t pol;
    hyb_cfg_t hyb; /* hybrid mode; its conf_min and lost_s also supervise the PLL alone */
} snl_cfg_t;

typedef struct {
    float i_alpha_a, i_beta_a;              /* measured at k */
    float u_alpha_prev_v, u_beta_prev_v;    /* the inverter's average voltage over [k-1, k) */
    bool u_valid;                           /* PWM on during [k-1, k) */
    float theta_mras_rad, omega_mras_rad_s; /* hybrid mode */
    bool mras_locked;
} snl_in_t;

typedef struct {
    float theta_e_rad, omega_e_rad_s;
    bool valid;          /* the polarity is resolved and the lock holds */
    bool startup;        /* the polarity test runs, or the lock is lost: hold the speed loop,
                            i_q* = 0 */
    float i_d_inject_a;  /* add to the d-axis current reference */
    float conf;          /* the PLL's confidence (cos 2d) */
    float err_rad;       /* the PLL's detector output this period, sin(2d)/2 */
    float theta_pll_rad; /* the PLL's own angle (hybrid: beside the blend) */
    float w_mras;        /* hybrid: the MRAS's weight */
    uint16_t pol_result; /* POL_* */
    float pol_asym;
    bool pol_done_now;  /* this period the polarity test ended (raise its event) */
    uint16_t lock;      /* SNL_LOCK_* (latched) */
    bool lock_lost_now; /* this period the lock was lost (raise the fault) */
} snl_out_t;

typedef struct {
    snl_cfg_t cfg;
    rpll_t pll;
    pol_t pol;
    hyb_t hyb;
    uint16_t lock;
    uint32_t n_low, n_low_max;
} snl_t;

void snl_init(snl_t *s, const snl_cfg_t *cfg);
void snl_step(snl_t *s, const snl_in_t *in, snl_out_t *out);

#endif
