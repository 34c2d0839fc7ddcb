/* Current-frequency (I/f) start of a back-EMF estimator (docs/sensorless.md): the MRAS sees no
 * back-EMF at rest, so the drive starts open loop and hands over to it at speed.
 *
 *   align:    a d-axis current ramps to i_a at the angle theta0: the rotor turns to it;
 *   ramp:     the current vector turns at omega_if, which follows the speed reference at
 *             `accel` (the rotor follows behind it by the load angle d, where
 *             1.5 p psi_f i_a sin d carries the load);
 *   handover: once |omega_if| >= handover speed and the estimator has been locked and within
 *             max_delta of the I/f angle for settle_s, the control takes the estimator's angle.
 *             The stator current is kept: in the estimator's frame it is
 *             (i_a cos d, i_a sin d), d = theta_if - theta_est; the speed loop's integrator
 *             starts at i_a sin d and the d-axis part decays to zero over decay_s;
 *   failed:   no handover within timeout_s at handover speed (a stalled or pulled-out rotor):
 *             the open-loop current stays on until the caller's lock supervision stops the drive.
 * While it runs the caller holds the speed loop at i_q_hold_a and adds i_d_inject_a to the d
 * reference (the angle slot's hold_refs interface). C28x-safe: float only. */
#ifndef IF_START_H
#define IF_START_H

#include <stdint.h>
#include <stdbool.h>

#define IFS_ALIGN    0u
#define IFS_RAMP     1u
#define IFS_DECAY    2u
#define IFS_DONE     3u
#define IFS_FAILED   4u
#define IFS_DISABLED 5u

typedef struct {
    float ts_s;
    float i_a;            /* the I/f current (0: no I/f start) */
    float accel_rad_s2;   /* electrical acceleration of the I/f angle */
    float handover_rad_s; /* electrical speed from which the estimator may take over */
    float theta0_rad;     /* alignment angle */
    float align_s, settle_s, decay_s, timeout_s;
    float max_delta_rad; /* the estimator within this of the I/f angle to take over */
} ifs_cfg_t;

typedef struct {
    ifs_cfg_t cfg;
    uint16_t phase;
    float theta_rad, omega_rad_s, t_s, settled_s, i_d_left_a, i_q_hold_a;
} ifs_t;

typedef struct {
    float omega_ref_rad_s; /* electrical speed reference (the profile's) */
    float theta_est_rad, omega_est_rad_s;
    bool est_locked;
} ifs_in_t;

typedef struct {
    bool open_loop; /* the I/f angle carries the control (align, ramp) */
    float theta_rad, omega_rad_s;
    bool hold_refs; /* hold the speed loop at i_q_hold_a */
    float i_q_hold_a;
    float i_d_inject_a; /* add to the d reference */
    bool handed_over_now;
    bool failed;
} ifs_out_t;

void ifs_init(ifs_t *s, const ifs_cfg_t *cfg);
void ifs_step(ifs_t *s, const ifs_in_t *in, ifs_out_t *out);

#endif
