/* Current-reference split (i_d = 0 or MTPA). See mtpa.h and docs/control.md. */
#include "mtpa.h"

#include <math.h>

void mtpa_split(const fw_motor_t *m, uint16_t mode, float i_s_a, fw_dq_t *out)
{
    const float dl = m->l_q_h - m->l_d_h;
    out->d = 0.0f;
    out->q = i_s_a;
    if (mode == MTPA_MODE_MTPA && dl > MTPA_DL_MIN_H) {
        const float is2 = i_s_a * i_s_a;
        const float psi = (m->psi_f_wb > 0.0f) ? m->psi_f_wb : 0.0f;
        const float den = psi + sqrtf(psi * psi + 8.0f * dl * dl * is2);
        float i_d, iq2;
        if (!(den > 0.0f)) {
            return; /* i_s = 0 and psi_f = 0 */
        }
        i_d = -2.0f * dl * is2 / den;
        iq2 = is2 - i_d * i_d;
        out->d = i_d;
        out->q = sqrtf((iq2 > 0.0f) ? iq2 : 0.0f);
        if (i_s_a < 0.0f) {
            out->q = -out->q;
        }
    }
}

float mtpa_torque_nm(const fw_motor_t *m, const fw_dq_t *i)
{
    return 1.5f * (float)m->pole_pairs * (m->psi_f_wb * i->q + (m->l_d_h - m->l_q_h) * i->d * i->q);
}
