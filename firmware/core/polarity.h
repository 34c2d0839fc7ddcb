/* Magnet polarity at start-up (docs/sensorless.md, "Polarity"): the saliency PLL locks to the d
 * axis or to its opposite (sin 2d). With the rotor at rest and locked, the d-axis current is
 * pulsed to +I then -I along the estimated d axis, and the inverse incremental inductance is
 * measured on each side from the ripple (while the PLL settles, a d-axis square wave of a third
 * of the pulse makes the ripple), g = sum(di_d U_d) / sum(Ts U_d^2). Iron saturates
 * asymmetrically in i_d because the magnet's flux adds to one side, so the relative asymmetry
 *     a = (g+ - g-) / (g+ + g-)
 * has the sign of the nominal magnetics' own (asym_expected: from the motor's flux map, or the
 * physics default, positive i_d saturating) when the estimate sits on the magnet's north pole,
 * and the opposite sign half a turn away. |a| below asym_min (a plant that does not saturate, or
 * a measurement too noisy) is "not resolved": the caller stops the motor and reports it. */
#ifndef POLARITY_H
#define POLARITY_H

#include <stdint.h>
#include <stdbool.h>

#include "proto_gen.h"

/* the results, as the polarity event reports them (enum polarity_result of the protocol) */
#define POL_RUNNING    PROTO_POLARITY_RESULT_RUNNING
#define POL_KEPT       PROTO_POLARITY_RESULT_KEPT    /* the estimate was on the magnet's d axis */
#define POL_FLIPPED    PROTO_POLARITY_RESULT_FLIPPED /* half a turn off, and turned */
#define POL_UNRESOLVED PROTO_POLARITY_RESULT_UNRESOLVED /* |asymmetry| below asym_min */
#define POL_NO_LOCK    PROTO_POLARITY_RESULT_NO_LOCK    /* no PLL lock before the pulses */

#define POL_SETTLE_EXCITE 0.33f /* d-axis square wave while settling, fraction of the pulse */
/* A PLL not yet confident at the end of the settling gets up to this many settling times more
 * before the test gives up (POL_NO_LOCK): a start near the detector's saddle (a quarter turn off)
 * may wander for tens of ms before it locks, and the confidence is a 10 ms running mean. */
#define POL_SETTLE_EXTEND 2u

typedef struct {
    float ts_s;
    float i_pulse_a;     /* d-axis pulse amplitude */
    float settle_s;      /* at rest, no current, before the pulses: the PLL locks */
    float pulse_s;       /* each pulse; the first third is the current's rise, not measured */
    float release_s;     /* no current after the pulses */
    float asym_expected; /* (g+ - g-)/(g+ + g-) of the nominal magnetics at +-i_pulse_a */
    float asym_min;      /* smallest |a| that resolves the polarity */
    float conf_min;      /* the PLL's confidence needed at the end of the settling */
} pol_cfg_t;

typedef struct {
    float di_d_a, u_d_v, i_d_a; /* from the PLL (rpll_out_t) */
    float conf;
    bool excited;
} pol_in_t;

typedef struct {
    float i_d_ref_a; /* the test's d-axis current reference (q axis: zero) */
    bool active;     /* the test owns the current references */
    bool flip_now;   /* this period: turn the estimate by pi */
    uint16_t result; /* POL_* */
    float asym;      /* measured a (valid once the pulses are done) */
} pol_out_t;

typedef struct {
    pol_cfg_t cfg;
    uint32_t tick;
    uint32_t n_settle, n_pulse, n_release;
    uint32_t n_extra; /* settling periods added while the PLL was not yet confident */
    float sum_num[2], sum_den[2];
    uint16_t result, pending;
    float asym;
} pol_t;

void pol_init(pol_t *p, const pol_cfg_t *cfg);
void pol_step(pol_t *p, const pol_in_t *in, pol_out_t *out);
/* Decide from the two measured sides (exposed for tests): a, and the POL_* result. */
uint16_t pol_decide(const pol_cfg_t *cfg, float g_pos, float g_neg, float *asym);

#endif
