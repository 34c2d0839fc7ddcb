/* Current-reference split: stator current magnitude command i_s -> (i_d*, i_q*). C28x-safe.
 * Modes match the protocol enum current_ref:
 *   MTPA_MODE_ID_ZERO: i_d* = 0, i_q* = i_s
 *   MTPA_MODE_MTPA:    maximum torque per ampere of an IPMSM (L_q > L_d):
 *     i_d* = (psi_f - sqrt(psi_f^2 + 8 (L_q - L_d)^2 i_s^2)) / (4 (L_q - L_d))   (<= 0)
 *     i_q* = sign(i_s) sqrt(i_s^2 - i_d*^2)
 *   evaluated in the cancellation-free form i_d* = -2 dL i_s^2 / (psi_f + sqrt(psi_f^2 + 8 dL^2 i_s^2)),
 *   dL = L_q - L_d; i_d* = 0 when dL <= MTPA_DL_MIN_H (SPMSM, or L_q < L_d). See docs/control.md. */
#ifndef MTPA_H
#define MTPA_H

#include <stdint.h>
#include "fw_types.h"

#define MTPA_MODE_ID_ZERO 0u
#define MTPA_MODE_MTPA    1u

#define MTPA_DL_MIN_H 1.0e-6f /* |L_q - L_d| below this: treat the motor as non-salient */

/* Unknown modes behave as MTPA_MODE_ID_ZERO. */
void mtpa_split(const fw_motor_t *m, uint16_t mode, float i_s_a, fw_dq_t *out);

/* Electromagnetic torque 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q). */
float mtpa_torque_nm(const fw_motor_t *m, const fw_dq_t *i);

#endif
