/* The angle slot: one stage of the control period (docs/architecture.md). In: the encoder's
 * reading when one is fitted (its observer runs in the measure stage, and its angle is always
 * logged as truth), the measured currents, the dq voltage applied during the previous period and
 * the current controller's prediction of this period's current. Out: the electrical angle and
 * speed the control uses, and whether they are valid.
 *
 * Today's occupant is the encoder (enc_angle.h). A sensorless estimator adds an ANGLE_SRC_x, a
 * member of the union in angle_t and a case in angle_slot.c. Selected by config_ctrl angle_src. */
#ifndef ANGLE_SLOT_H
#define ANGLE_SLOT_H

#include <stdint.h>
#include <stdbool.h>

#include "enc_angle.h"
#include "proto_gen.h"

#define ANGLE_SRC_ENCODER PROTO_ANGLE_SRC_ENCODER /* config_ctrl angle_src */

typedef struct {
    uint16_t src; /* ANGLE_SRC_* */
    uint16_t pole_pairs;
    float ts_s; /* control period */
} angle_cfg_t;

typedef struct {
    const enc_out_t *enc;         /* the encoder's reading this period; NULL when none is fitted */
    float i_alpha_a, i_beta_a;    /* measured at k */
    float u_d_prev_v, u_q_prev_v; /* average dq voltage applied during [k-1, k), previous frame */
    float i_d_pred_a, i_q_pred_a; /* the current controller's prediction of i(k), previous frame */
} angle_in_t;

typedef struct {
    float theta_e_rad; /* electrical angle at k, [0, 2pi) */
    float omega_e_rad_s;
    float omega_m_rad_s;
    float speed_rpm;
    bool valid; /* false: the source cannot tell the angle (no encoder, not locked) */
} angle_out_t;

typedef struct {
    angle_cfg_t cfg;
    angle_out_t last;
} angle_t;

bool angle_src_known(uint16_t src);
void angle_init(angle_t *a,
                const angle_cfg_t *cfg); /* an unknown source falls back to the encoder */
void angle_step(angle_t *a, const angle_in_t *in, angle_out_t *out);

#endif
