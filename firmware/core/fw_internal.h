/* Internal interface between the firmware application's files (fw.c: state and control period,
 * fw_cmd.c: host commands, fw_msg.c: messages to the host). Stages of the control period only
 * raise events (fw_raise) and ask for a status frame (status_due); fw_flush sends them once at
 * the end of the period or of the command. Not for boards: they use fw.h. */
#ifndef FW_INTERNAL_H
#define FW_INTERNAL_H

#include "fw.h"

/* Hard ceilings on what the host may configure (fw_cmd.c): whatever it sends, the protection stays on */
#define FW_HEARTBEAT_MAX_S 10.0f   /* the heartbeat timeout cannot be switched off or made longer */
#define FW_I_TRIP_MAX_A    2000.0f /* over-current trip level */
#define FW_SPEED_TRIP_MAX_RPM 100000.0f
#define FW_V_DC_MAX_V         2000.0f
#define FW_LOAD_MAX_NM        10000.0f
#define FW_GAIN_MAX           1.0e7f /* speed PI gains, observer bandwidth */

#define FW_STOP_RAMP_RPM_S   3000.0f /* quick-stop deceleration */
#define FW_STOP_SPEED_RPM    3.0f    /* mean speed below this over a window: PWM goes off */
#define FW_STOP_HOLD_S       0.05f   /* the window: zero reference held this long before PWM off */
#define FW_STOP_TIMEOUT_S    3.0f    /* PWM off after this long in any case */
#define FW_RPM_PER_RAD_S     9.549296585513720f
#define FW_SPEED_REF_WEIGHT  0.7f  /* set-point weight of the speed PI's proportional path */
#define FW_DITHER_PERIOD     22u   /* q-current dither: not a divisor of the speed-loop period */
#define FW_IFS_ALIGN_S       0.2f  /* I/f start: the alignment current's ramp (held half as long) */
#define FW_IFS_SETTLE_S      0.05f /* ... the MRAS locked and near the I/f angle this long */
#define FW_IFS_DECAY_S       0.1f  /* ... the d current of the handover decays over this */
#define FW_IFS_TIMEOUT_S     0.5f  /* ... no handover this long at handover speed: lost lock */
#define FW_IFS_MAX_DELTA_RAD 1.2f  /* ... the load angle it accepts (the pull-out is pi/2) */
#define FW_CC_MEAN_TAU_S                                                                           \
    1.0e-3f /* low-pass of the applied dq voltage a current-controller handover starts from */
#define FW_DITHER_GAIN 0.6f /* peak-to-peak, as a fraction of one vector's current step */
/* the sensorless start (docs/sensorless.md): the PLL settles at rest, then +-pulses on d */
#define FW_POL_SETTLE_S         0.04f
#define FW_POL_PULSE_S          0.01f
#define FW_POL_RELEASE_S        0.005f
#define FW_POL_CONF_MIN         0.8f  /* the PLL's confidence needed before the pulses */
#define FW_POL_ASYM_DEFAULT     0.05f /* no host configuration: positive i_d saturates first */
#define FW_POL_ASYM_MIN_DEFAULT 0.02f

/* fw.c */
void fw_raise(fw_t *f, uint16_t code, int32_t arg); /* an event, sent at the end of the period */
void fw_enter_stopping(fw_t *f, uint16_t reason);
void fw_pwm_off(fw_t *f, uint16_t new_state, uint16_t reason);
void fw_trip(fw_t *f, uint16_t fault_bits);
uint16_t fw_start_run(fw_t *f);

/* fw_msg.c */
void fw_flush(fw_t *f); /* the raised events in order, then the status frame if one is due */
void fw_send_ack(fw_t *f, uint16_t cmd_id, uint16_t cmd_seq, uint16_t status);
void fw_send_identify(fw_t *f);
void fw_send_capture_chunk(fw_t *f, uint16_t offset);
void fw_send_status(fw_t *f);
void fw_send_params(fw_t *f, uint16_t slot);
void fw_tel_start(fw_t *f); /* the telemetry streams' phases of tick 0 (fw_start_run) */
void fw_send_telemetry(fw_t *f);

/* fw_snl.c: the sensorless estimator's configuration from the host's frames (or defaults) */
void fw_snl_config(const fw_t *f, snl_cfg_t *sc);

#endif
