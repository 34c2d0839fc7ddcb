/* The saliency phase detector of the ripple PLL (ripple_err.h). */
#include "ripple_err.h"

#include <string.h>

void rerr_gamma_linear(rerr_gamma_t *m, float l_d_h, float l_q_h)
{
    memset(m, 0, sizeof(*m));
    m->a0 = l_d_h > 0.0f ? 1.0f / l_d_h : 0.0f;
    m->b0 = l_q_h > 0.0f ? 1.0f / l_q_h : 0.0f;
}

void rerr_gamma_at(const rerr_gamma_t *m, float i_d_a, float i_q_a, rerr_g_t *g)
{
    const float d2 = i_d_a * i_d_a, q2 = i_q_a * i_q_a;
    g->g_dd = m->a0 + m->a1 * i_d_a + m->a2 * d2 + m->a3 * q2;
    g->g_qq = m->b0 + m->b1 * i_d_a + m->b2 * d2 + m->b3 * q2;
    g->g_dq = i_q_a * (m->c0 + m->c1 * i_d_a);
}

void rerr_eval(const rerr_in_t *in, float ts_s, rerr_out_t *out)
{
    const float dc = 0.5f * (in->g.g_dd - in->g.g_qq), ds = in->g.g_dq;
    const float num_s = in->e_q_a * in->u_d_v + in->e_d_a * in->u_q_v;
    const float num_c = in->e_d_a * in->u_d_v - in->e_q_a * in->u_q_v;
    const float u2 = in->u_d_v * in->u_d_v + in->u_q_v * in->u_q_v;
    out->sn = num_s * dc - num_c * ds;
    out->cn = num_c * dc + num_s * ds;
    out->norm = ts_s * (dc * dc + ds * ds) * u2;
}
