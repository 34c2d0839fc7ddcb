/* The angle slot: one stage of the control period (docs/architecture.md, docs/sensorless.md).
 * In: the encoder's reading when one is fitted (its observer runs in the measure stage, and its
 * angle is always logged as truth), the measured currents, the stationary-frame voltage the
 * inverter applied during the previous period (and the same in dq with the current controller's
 * prediction of this period's current). Out: the electrical angle and speed of the occupant,
 * whether they are valid, and for an estimator its lock, confidence and error signal.
 *
 * Occupants: the encoder (enc_angle.h), the MRAS (mras.h), the current-ripple PLL
 * (est_ripple_pll.h, with the polarity test at start) and the hybrid of the ripple PLL and the
 * MRAS (hybrid.h). A new occupant adds a member of the union in angle_t and a case in
 * angle_slot.c. Selected by
 * config_ctrl angle_src; an estimator's angle closes the loop unless the running segment asks for
 * the encoder (segment flag angle_encoder), in which case it runs beside it. */
#ifndef ANGLE_SLOT_H
#define ANGLE_SLOT_H

#include <stdint.h>
#include <stdbool.h>

#include "enc_angle.h"
#include "mras.h"
#include "if_start.h"
#include "sensorless.h"
#include "proto_gen.h"

#define ANGLE_SRC_ENCODER    PROTO_ANGLE_SRC_ENCODER /* config_ctrl angle_src */
#define ANGLE_SRC_MRAS       PROTO_ANGLE_SRC_MRAS
#define ANGLE_SRC_RIPPLE_PLL PROTO_ANGLE_SRC_RIPPLE_PLL
#define ANGLE_SRC_HYBRID     PROTO_ANGLE_SRC_HYBRID

typedef struct {
    uint16_t src; /* ANGLE_SRC_* */
    uint16_t pole_pairs;
    float ts_s; /* control period */
    /* estimators */
    float bw_rad_s;      /* tracking bandwidth (0: the occupant's default) */
    float min_speed_rpm; /* not locked below this (mechanical) speed */
    float max_speed_rpm; /* the estimate is clamped to +-this (the over-speed trip) */
    float theta0_rad;    /* initial estimated electrical angle */
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb; /* the motor file's values */
    float j_kgm2;
    const snl_cfg_t *snl; /* ripple PLL, hybrid: the sensorless configuration (sensorless.h) */
    ifs_cfg_t ifs;        /* MRAS: its current-frequency start (if_start.h; i_a 0: none) */
} angle_cfg_t;

typedef struct {
    const enc_out_t *enc;      /* the encoder's reading this period; NULL when none is fitted */
    float i_alpha_a, i_beta_a; /* measured at k */
    float u_alpha_prev_v, u_beta_prev_v; /* average voltage applied during [k-1, k), stationary */
    float u_d_prev_v, u_q_prev_v;        /* the same in dq (previous frame, mid-period) */
    float i_d_pred_a, i_q_pred_a; /* the current controller's prediction of i(k), previous frame */
    float omega_ref_e_rad_s;      /* the speed reference (previous period), electrical */
} angle_in_t;

typedef struct {
    float theta_e_rad; /* electrical angle at k, [0, 2pi) */
    float omega_e_rad_s;
    float omega_m_rad_s;
    float speed_rpm;
    bool valid;       /* false: the source cannot tell the angle (no encoder) */
    bool locked;      /* the occupant tracks the rotor (the encoder: whenever valid) */
    float confidence; /* 0..1 */
    float err_rad;    /* an estimator's normalised error signal (0 for the encoder) */
    /* ripple PLL, hybrid: the start-up polarity test owns the current references while it runs
     * (hold the speed loop, i_q* = 0), and the d axis gets i_d_inject_a added (test pulses or the
     * estimator's excitation at rest) */
    bool hold_refs;
    float i_d_inject_a;
    float i_q_hold_a;        /* the q reference (and the speed loop's output) while held */
    bool open_loop;          /* the MRAS's current-frequency start carries the angle */
    uint16_t if_event_now;   /* PROTO_EVENT_IF_HANDOVER / _IF_FAILED this period, else 0 */
    uint16_t pol_result_now; /* POL_* when the polarity test ended this period, else 0 */
    float pol_asym;
} angle_out_t;

typedef struct {
    angle_cfg_t cfg;
    angle_out_t last;
    ifs_t ifs; /* MRAS: the current-frequency start */
    bool if_failed_told;
    union {
        mras_t mras;
        struct {
            mras_t mras; /* hybrid only */
            snl_t snl;
        } sl;
    } u;
} angle_t;

bool angle_src_known(uint16_t src);
bool angle_src_is_estimator(uint16_t src);
void angle_init(angle_t *a,
                const angle_cfg_t *cfg); /* an unknown source falls back to the encoder */
void angle_step(angle_t *a, const angle_in_t *in, angle_out_t *out);
/* The encoder's reading as an angle output (what an angle_encoder segment closes the loop on). */
void angle_encoder_out(const angle_in_t *in, angle_out_t *out);

#endif
