/* Reference-frame transforms and angle wrapping (C28x-safe, header only).
 *
 * Conventions (docs/control.md):
 *   Clarke, amplitude-invariant:  x_alpha = (2 x_a - x_b - x_c) / 3,  x_beta = (x_b - x_c) / sqrt(3)
 *   Park (alpha/beta -> d/q at angle theta, given c = cos(theta), s = sin(theta)):
 *       x_d =  c x_alpha + s x_beta,   x_q = -s x_alpha + c x_beta
 *   Inverse Park: x_alpha = c x_d - s x_q,  x_beta = s x_d + c x_q
 * A balanced set of amplitude X gives |x_alpha + j x_beta| = X. */
#ifndef TRANSFORMS_H
#define TRANSFORMS_H

#include <math.h>
#include "fw_types.h"

#define TF_SQRT3_F      1.73205080756888f
#define TF_INV_SQRT3_F  0.577350269189626f
#define TF_SQRT3_BY_2_F 0.866025403784439f

/* Three-phase Clarke (no assumption that a + b + c = 0; the zero sequence is dropped). */
static inline void tf_clarke(float a, float b, float c, float *alpha, float *beta)
{
    *alpha = (2.0f * a - b - c) * (1.0f / 3.0f);
    *beta = (b - c) * TF_INV_SQRT3_F;
}

/* Two-phase Clarke, assuming a + b + c = 0 (two current sensors). */
static inline void tf_clarke2(float a, float b, float *alpha, float *beta)
{
    *alpha = a;
    *beta = (a + 2.0f * b) * TF_INV_SQRT3_F;
}

/* Inverse Clarke (alpha/beta -> phases, zero sequence = 0). */
static inline void tf_inv_clarke(float alpha, float beta, float *a, float *b, float *c)
{
    *a = alpha;
    *b = -0.5f * alpha + TF_SQRT3_BY_2_F * beta;
    *c = -0.5f * alpha - TF_SQRT3_BY_2_F * beta;
}

/* Park with a precomputed cos/sin of the rotor angle. */
static inline void tf_park(float alpha, float beta, float c, float s, float *d, float *q)
{
    *d = c * alpha + s * beta;
    *q = -s * alpha + c * beta;
}

/* Inverse Park with a precomputed cos/sin of the rotor angle. */
static inline void tf_inv_park(float d, float q, float c, float s, float *alpha, float *beta)
{
    *alpha = c * d - s * q;
    *beta = s * d + c * q;
}

/* Wrap an angle into [0, 2 pi). Exact for |x| up to a few thousand turns (float resolution). */
static inline float tf_wrap_2pi(float x_rad)
{
    float r = x_rad - FW_TWO_PI_F * floorf(x_rad * (1.0f / FW_TWO_PI_F));
    if (r >= FW_TWO_PI_F) { /* rounding at the top edge */
        r -= FW_TWO_PI_F;
    }
    if (r < 0.0f) {
        r = 0.0f;
    }
    return r;
}

/* Wrap an angle into (-pi, pi]. */
static inline float tf_wrap_pi(float x_rad)
{
    float r = tf_wrap_2pi(x_rad);
    if (r > FW_PI_F) {
        r -= FW_TWO_PI_F;
    }
    return r;
}

#endif
