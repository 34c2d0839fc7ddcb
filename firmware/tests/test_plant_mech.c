/* Unit tests of the emulator's plant (firmware/sim/plant*.c): PWM off and the mechanics. The
 * electrical tests are in test_plant.c. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "plant.h"
#include "plant_cmd.h"

#define PI     3.14159265358979323846
#define TWO_PI (2.0 * PI)

static int finite3(double a, double b, double c)
{
    return isfinite(a) && isfinite(b) && isfinite(c);
}

static double maxd(double a, double b)
{
    return a > b ? a : b;
}

static void test_pwm_off(void)
{
    plant_cfg_t cfg;
    plant_t p;
    plant_truth_t t;
    fw_cmd_t on, off;
    int k, zero_at = -1, ok = 1, stays = 1;

    cfg_base(&cfg);
    cfg.v_drop_v = 1.0;
    plant_init(&p, &cfg);
    cmd_set(&off, 0, 0, 0, false, 0.0);
    cmd_set(&on, 1, 0, 0, true, 0.0);
    plant_set_mech(&p, 0.0, 1000.0 * PI / 30.0, true);
    plant_set_currents(&p, -5.0, 10.0);
    for (k = 0; k < 2000; k++) {
        plant_step(&p, &off);
        plant_truth(&p, &t);
        if (!finite3(t.i_d_a, t.i_q_a, t.u_d_v))
            ok = 0;
        if (zero_at < 0 && t.i_d_a == 0.0 && t.i_q_a == 0.0)
            zero_at = k;
        if (zero_at >= 0 && (t.i_d_a != 0.0 || t.i_q_a != 0.0))
            stays = 0;
    }
    printf("PWM off at 1000 r/min from |i| = 11.2 A: currents exactly zero after %d periods\n",
           zero_at + 1);
    CHECK(ok, "PWM off: no NaN");
    CHECK(zero_at >= 0 && zero_at < 20, "PWM off: currents reach zero within 1 ms");
    CHECK(stays, "PWM off: currents stay exactly zero (back-EMF below v_dc)");
    CHECK(fabs(sqrt(t.u_d_v * t.u_d_v + t.u_q_v * t.u_q_v) - 4 * 1000.0 * PI / 30.0 * 0.18) < 1e-6,
          "PWM off, open: the terminals show the back-EMF w_e psi_f");

    /* after an ideal voltage source (plant_step_udq) the diodes take over just the same */
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.0, 500.0 * PI / 30.0, true);
    for (k = 0; k < 200; k++) {
        plant_step_udq(&p, -20.0, 150.0, 0.0);
    }
    plant_truth(&p, &t);
    CHECK(fabs(t.i_q_a) > 1.0, "udq drive built up a current");
    for (k = 0; k < 40; k++) {
        plant_step(&p, &off);
    }
    plant_truth(&p, &t);
    CHECK(t.i_d_a == 0.0 && t.i_q_a == 0.0, "PWM off after plant_step_udq: currents decay to zero");

    /* free rotor, switching on and off again */
    plant_init(&p, &cfg);
    plant_set_mech(&p, 1.0, 50.0, false);
    for (k = 0; k < 400; k++) {
        plant_step(&p, (k / 37) & 1 ? &on : &off);
        plant_truth(&p, &t);
        if (!finite3(t.i_d_a, t.i_q_a, t.omega_m_rad_s))
            ok = 0;
    }
    CHECK(ok, "PWM on/off toggling: no NaN");

    /* back-EMF above the DC link (60 V at 1000 r/min: line-line peak 131 V): the diodes rectify,
     * the machine brakes and feeds the DC link; currents stay bounded */
    cfg.v_dc_v = 60.0;
    plant_init(&p, &cfg);
    plant_set_mech(&p, 0.0, 1000.0 * PI / 30.0, true);
    {
        double tsum = 0.0, imax = 0.0, jumps = 0.0, iprev = 0.0;
        for (k = 0; k < 4000; k++) {
            plant_step(&p, &off);
            plant_truth(&p, &t);
            if (!finite3(t.i_a_a, t.i_b_a, t.torque_nm))
                ok = 0;
            if (k >= 2000) {
                tsum += t.torque_nm;
                imax = maxd(imax, fabs(t.i_a_a));
                jumps = maxd(jumps, fabs(t.i_a_a - iprev));
            }
            iprev = t.i_a_a;
        }
        printf("PWM off, 60 V link at 1000 r/min: braking torque %.3f N m, peak phase current %.2f "
               "A, largest step %.3f A\n",
               tsum / 2000, imax, jumps);
        CHECK(ok, "rectifying: no NaN");
        CHECK(tsum / 2000 < -0.05, "rectifying: mean torque brakes the rotor");
        CHECK(imax > 1.0 && imax < 100.0, "rectifying: currents flow and stay bounded");
        CHECK(jumps < 0.5 * imax, "rectifying: no period-to-period chatter");
    }
}

/* ------------------------------------------------------------------ encoder */

static void test_mechanics(void)
{
    plant_cfg_t cfg;
    plant_t p;
    plant_truth_t t;
    fw_cmd_t c;
    int k, stuck = 1, stays = 1;
    const double J = 0.0036;

    cfg_base(&cfg);
    plant_init(&p, &cfg);
    cmd_set(&c, 0, 0, 0, false, -2.0); /* a driving load of 2 N m, PWM off, no current */
    for (k = 0; k < 2000; k++) {
        plant_step(&p, &c);
    }
    plant_truth(&p, &t);
    CHECK_NEAR(t.omega_m_rad_s, 2.0 / J * 0.1, 1e-9, "constant torque: w = T t / J");
    CHECK_NEAR(t.theta_m_rad, fmod(0.5 * 2.0 / J * 0.01, TWO_PI), 1e-9,
               "constant torque: theta = T t^2 / 2J");
    CHECK_NEAR(t.i_d_a, 0.0, 0.0, "no current while the back-EMF is below v_dc");

    /* viscous friction: exponential approach to T / b */
    cfg.b_visc_nms = 0.01;
    plant_init(&p, &cfg);
    for (k = 0; k < 4000; k++) {
        plant_step(&p, &c);
    }
    plant_truth(&p, &t);
    CHECK_NEAR(t.omega_m_rad_s, 2.0 / 0.01 * (1.0 - exp(-0.01 / J * 0.2)), 1e-8,
               "viscous: w = T/b (1 - exp(-b t / J))");

    /* Coulomb friction: sticks below T_c, breaks away above, stops and stays stopped */
    cfg.b_visc_nms = 0.0;
    cfg.t_coulomb_nm = 0.5;
    plant_init(&p, &cfg);
    cmd_set(&c, 0, 0, 0, false, -0.3);
    for (k = 0; k < 1000; k++) {
        plant_step(&p, &c);
        if (p.omega_m_rad_s != 0.0 || p.theta_m_rad != 0.0)
            stuck = 0;
    }
    CHECK(stuck, "Coulomb: load below T_c, the rotor does not move at all");
    cmd_set(&c, 0, 0, 0, false, -1.0);
    for (k = 0; k < 1000; k++) {
        plant_step(&p, &c);
    }
    plant_truth(&p, &t);
    CHECK_NEAR(t.omega_m_rad_s, 0.5 / J * 0.05, 1e-9,
               "Coulomb: breakaway, acceleration (T - T_c) / J");
    cmd_set(&c, 0, 0, 0, false, 0.0);
    for (k = 0; k < 3000; k++) {
        plant_step(&p, &c);
        if (k > 1100 && p.omega_m_rad_s != 0.0)
            stays = 0;
    }
    CHECK(stays, "Coulomb: coasting stops at w = 0 and stays there (no chatter)");
    cmd_set(&c, 0, 0, 0, false, 0.7); /* reverse breakaway */
    for (k = 0; k < 100; k++) {
        plant_step(&p, &c);
    }
    plant_truth(&p, &t);
    CHECK(t.omega_m_rad_s < 0.0, "Coulomb: breakaway in the other direction");
}

int main(void)
{
    test_pwm_off();
    test_mechanics();
    return CHECK_DONE();
}
