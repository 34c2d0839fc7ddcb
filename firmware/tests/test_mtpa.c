/* MTPA / i_d = 0 current split tests: MTPA against a brute-force search over the current angle,
 * signs, magnitude, degenerate motors, the torque formula. */
#include <stdio.h>
#include <math.h>
#include "check.h"
#include "mtpa.h"

#define PI_D 3.14159265358979323846

static fw_motor_t paper_a(void)
{
    fw_motor_t m;
    m.pole_pairs = 4u;
    m.r_s_ohm = 0.9f;
    m.l_d_h = 0.005f;
    m.l_q_h = 0.012f;
    m.psi_f_wb = 0.18f;
    m.j_kgm2 = 0.0036f;
    m.i_max_a = 15.0f;
    m.speed_max_rpm = 1500.0f;
    return m;
}

static double torque_d(const fw_motor_t *m, double i_d, double i_q)
{
    return 1.5 * m->pole_pairs * (m->psi_f_wb * i_q + ((double)m->l_d_h - m->l_q_h) * i_d * i_q);
}

/* Maximum torque for |i| = i_s by a fine search over the angle from the q axis (i_d <= 0 side and
 * the whole circle to be safe). */
static double brute_best(const fw_motor_t *m, double i_s, double *i_d_best)
{
    double best = -1e30;
    int k;
    for (k = 0; k <= 200000; k++) {
        const double b = -PI_D + 2.0 * PI_D * k / 200000.0;
        const double i_d = -i_s * sin(b), i_q = i_s * cos(b);
        const double t = torque_d(m, i_d, i_q);
        if (t > best) {
            best = t;
            *i_d_best = i_d;
        }
    }
    return best;
}

static void test_mtpa_vs_brute_force(void)
{
    fw_motor_t m = paper_a();
    static const double is[6] = { 0.5, 2.0, 5.0, 10.0, 15.0, 40.0 };
    int n;
    for (n = 0; n < 6; n++) {
        fw_dq_t i;
        double id_b, t_b, t_m;
        mtpa_split(&m, MTPA_MODE_MTPA, (float)is[n], &i);
        t_b = brute_best(&m, is[n], &id_b);
        t_m = mtpa_torque_nm(&m, &i);
        printf(
            "  i_s %5.1f A: MTPA i_d %+.4f i_q %.4f A, %.5f N m; brute force i_d %+.4f A, %.5f N m;"
            " i_d = 0: %.5f N m\n",
            is[n], i.d, i.q, t_m, id_b, t_b, torque_d(&m, 0.0, is[n]));
        CHECK(t_m >= t_b * (1.0 - 1e-5), "MTPA torque equals the brute-force maximum");
        CHECK_NEAR(i.d, id_b, 1e-3 * is[n] + 1e-3, "MTPA i_d equals the brute-force optimum");
        CHECK_NEAR(sqrt((double)i.d * i.d + (double)i.q * i.q), is[n], 1e-5 * is[n], "|i| = i_s");
        CHECK(i.d <= 0.0f, "i_d <= 0 for L_q > L_d");
        CHECK(t_m >= torque_d(&m, 0.0, is[n]), "MTPA beats i_d = 0 per ampere");
    }
}

static void test_signs(void)
{
    fw_motor_t m = paper_a();
    fw_dq_t a, b;
    mtpa_split(&m, MTPA_MODE_MTPA, 8.0f, &a);
    mtpa_split(&m, MTPA_MODE_MTPA, -8.0f, &b);
    CHECK(b.d <= 0.0f && b.q < 0.0f, "negative i_s: i_d <= 0, i_q < 0");
    CHECK_NEAR(a.d, b.d, 1e-6, "same i_d for +-i_s");
    CHECK_NEAR(a.q, -b.q, 1e-6, "mirrored i_q");
    CHECK_NEAR(mtpa_torque_nm(&m, &b), -mtpa_torque_nm(&m, &a), 1e-5, "braking torque mirrored");
    mtpa_split(&m, MTPA_MODE_MTPA, 0.0f, &a);
    CHECK(a.d == 0.0f && a.q == 0.0f, "zero command gives zero currents");
}

static void test_id_zero(void)
{
    fw_motor_t m = paper_a();
    fw_dq_t a;
    mtpa_split(&m, MTPA_MODE_ID_ZERO, 7.5f, &a);
    CHECK(a.d == 0.0f && a.q == 7.5f, "id_zero: i_d = 0, i_q = i_s");
    mtpa_split(&m, MTPA_MODE_ID_ZERO, -3.0f, &a);
    CHECK(a.d == 0.0f && a.q == -3.0f, "id_zero: negative");
    mtpa_split(&m, 99u, 5.0f, &a);
    CHECK(a.d == 0.0f && a.q == 5.0f, "unknown mode behaves as id_zero");
    CHECK_NEAR(mtpa_torque_nm(&m, &a), 1.5 * 4 * 0.18 * 5.0, 1e-5,
               "torque = 1.5 p psi_f i_q at i_d = 0");
}

static void test_degenerate(void)
{
    fw_motor_t m = paper_a();
    fw_dq_t a;
    double id_b;
    /* SPMSM (paper B): L_d = L_q -> i_d = 0 */
    m.l_d_h = 0.0085f;
    m.l_q_h = 0.0085f;
    mtpa_split(&m, MTPA_MODE_MTPA, 6.0f, &a);
    CHECK(a.d == 0.0f && a.q == 6.0f, "non-salient: MTPA = i_d = 0");
    /* tiny saliency: continuous, no cancellation blow-up */
    m.l_q_h = 0.0085f + 2e-6f;
    mtpa_split(&m, MTPA_MODE_MTPA, 6.0f, &a);
    CHECK(a.d <= 0.0f && a.d > -0.01f, "tiny saliency: i_d small and <= 0");
    /* L_q < L_d (e.g. an estimate overshooting on an SPMSM): clamped to i_d = 0 */
    m.l_q_h = 0.008f;
    mtpa_split(&m, MTPA_MODE_MTPA, 6.0f, &a);
    CHECK(a.d == 0.0f && a.q == 6.0f, "L_q < L_d: i_d = 0");
    /* synchronous reluctance (psi_f = 0): 45 degrees */
    m = paper_a();
    m.psi_f_wb = 0.0f;
    mtpa_split(&m, MTPA_MODE_MTPA, 10.0f, &a);
    CHECK_NEAR(a.d, -10.0 / sqrt(2.0), 1e-4, "psi_f = 0: i_d = -i_s/sqrt(2)");
    CHECK_NEAR(a.q, 10.0 / sqrt(2.0), 1e-4, "psi_f = 0: i_q = i_s/sqrt(2)");
    CHECK(mtpa_torque_nm(&m, &a) >= brute_best(&m, 10.0, &id_b) * (1.0 - 1e-5),
          "psi_f = 0: optimum");
    mtpa_split(&m, MTPA_MODE_MTPA, 0.0f, &a);
    CHECK(a.d == 0.0f && a.q == 0.0f, "psi_f = 0 and i_s = 0: no division by zero");
}

/* The closed form printed in the brief and the cancellation-free form agree. */
static void test_closed_forms(void)
{
    fw_motor_t m = paper_a();
    const double dl = (double)m.l_q_h - m.l_d_h, psi = m.psi_f_wb;
    int k;
    for (k = 1; k <= 30; k++) {
        fw_dq_t a;
        const double is = 0.5 * k;
        const double id_ref = (psi - sqrt(psi * psi + 8.0 * dl * dl * is * is)) / (4.0 * dl);
        mtpa_split(&m, MTPA_MODE_MTPA, (float)is, &a);
        CHECK_NEAR(a.d, id_ref, 1e-5 * is, "i_d = (psi - sqrt(psi^2 + 8 dL^2 i_s^2)) / (4 dL)");
    }
}

int main(void)
{
    test_mtpa_vs_brute_force();
    test_signs();
    test_id_zero();
    test_degenerate();
    test_closed_forms();
    return CHECK_DONE();
}
