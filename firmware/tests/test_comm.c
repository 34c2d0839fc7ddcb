/* Commissioning helpers (comm.c): the regression solver recovers known coefficients, the
 * inverter model opposes the current with the measured plateau, the duty output reproduces the
 * commanded voltage, the sequence runs only the requested steps and the offsets step measures
 * planted offsets with the PWM off. */
#include <stdio.h>
#include <string.h>
#include <math.h>
#include "check.h"
#include "comm.h"
#include "enc_angle.h"
#include "plant.h"
#include "transforms.h"

static comm_cfg_t cfg(uint16_t steps)
{
    comm_cfg_t c;
    memset(&c, 0, sizeof(c));
    c.steps = steps;
    c.i_test_a = 7.5f;
    c.spin_rpm = 750.0f;
    c.ts_s = 50e-6f;
    c.v_dc_min_v = 400.0f;
    c.v_dc_max_v = 750.0f;
    c.motor.pole_pairs = 4u;
    c.motor.r_s_ohm = 0.9f;
    c.motor.l_d_h = 0.005f;
    c.motor.l_q_h = 0.012f;
    c.motor.psi_f_wb = 0.18f;
    c.motor.j_kgm2 = 0.0036f;
    c.motor.i_max_a = 15.0f;
    c.motor.speed_max_rpm = 1500.0f;
    c.i_dt_nom_a = 0.5f;
    c.v_drop_nom_v = 1.0f;
    c.enc_counts = 10000u;
    return c;
}

static void test_regression(void)
{
    comm_reg_t r;
    float a[COMM_REG_N];
    uint16_t k;
    comm_reg_reset(&r);
    for (k = 0u; k < 200u; k++) {
        float x[COMM_REG_N];
        x[0] = sinf(0.1f * (float)k);
        x[1] = cosf(0.37f * (float)k);
        x[2] = (float)(k % 7u) - 3.0f;
        x[3] = 1.0f;
        comm_reg_add(&r, x, 2.0f * x[0] - 1.0f * x[1] + 0.5f * x[2] + 3.0f);
    }
    CHECK(comm_reg_solve(&r, COMM_REG_N, a), "regression solvable");
    CHECK_NEAR(a[0], 2.0, 1e-3, "a0");
    CHECK_NEAR(a[1], -1.0, 1e-3, "a1");
    CHECK_NEAR(a[2], 0.5, 1e-3, "a2");
    CHECK_NEAR(a[3], 3.0, 1e-3, "a3");
    comm_reg_reset(&r);
    CHECK(!comm_reg_solve(&r, COMM_REG_N, a), "no data: not solvable");
}

static void test_inverter_model(void)
{
    comm_t c;
    comm_cfg_t k = cfg(1u);
    const float i3[3] = { 5.0f, -2.5f, -2.5f };
    float d, q;
    comm_start(&c, &k);
    c.v_dc = 540.0f;
    comm_inv_dist(&c, i3, 1.0f, 0.0f, &d, &q);
    CHECK_NEAR(d, 0.0, 1e-6, "no model yet: no distortion");
    c.have_inv = true;
    c.inv_v = 22.6f;
    c.inv_i_dt_a = 0.5f;
    c.inv_vdc_v = 540.0f;
    comm_inv_dist(&c, i3, 1.0f, 0.0f, &d, &q);
    /* along phase a past the knee: -(2/3) V (1 + 1/2) = -V * 4/3 */
    CHECK_NEAR(d, -22.6 * 4.0 / 3.0, 1e-3, "plateau along phase a");
    CHECK_NEAR(q, 0.0, 1e-4, "no q component along phase a");
    c.v_dc = 270.0f; /* the dead-time part halves with the DC voltage, the drop stays */
    CHECK_NEAR(comm_inv_plateau(&c, 270.0f), (22.6 - 1.0) * 0.5 + 1.0, 1e-3, "plateau scales");
    CHECK_NEAR(comm_smooth_sign(0.1f, 0.5f), 0.2 * (27.0 + 0.04) / (27.0 + 0.36), 1e-6, "sigma");
    CHECK(comm_smooth_sign(2.0f, 0.5f) == 1.0f, "sigma saturates");
}

static void test_voltage_output(void)
{
    comm_t c;
    comm_cfg_t k = cfg(1u);
    comm_out_t o;
    const float th = 0.7f;
    float ua, ub, uc, al, be, d, q;
    comm_start(&c, &k);
    c.v_dc = 540.0f;
    comm_voltage(&c, cosf(th), sinf(th), 30.0f, -80.0f, &o);
    CHECK(o.pwm_on, "pwm on");
    ua = (o.duty[0] - 0.5f) * 540.0f;
    ub = (o.duty[1] - 0.5f) * 540.0f;
    uc = (o.duty[2] - 0.5f) * 540.0f;
    tf_clarke(ua, ub, uc, &al, &be);
    tf_park(al, be, cosf(th), sinf(th), &d, &q);
    CHECK_NEAR(d, 30.0, 1e-3, "u_d reproduced");
    CHECK_NEAR(q, -80.0, 1e-3, "u_q reproduced");
}

static void test_offsets_step(void)
{
    comm_t c;
    comm_cfg_t k = cfg(1u << PROTO_COMMISSION_STEP_OFFSETS);
    comm_in_t in;
    comm_out_t o;
    uint32_t n;
    uint16_t st = COMM_RUNNING;
    comm_start(&c, &k);
    memset(&in, 0, sizeof(in));
    in.v_dc_v = 540.0f;
    for (n = 0u; n < 100000u && st == COMM_RUNNING; n++) {
        const float noise = (n % 2u) ? 0.01f : -0.01f;
        in.i_a_a = 0.05f + noise;
        in.i_b_a = -0.03f - noise;
        in.i_c_a = 0.02f;
        st = comm_step(&c, &in, &o);
        CHECK(!o.pwm_on || st != COMM_RUNNING, "PWM off while measuring offsets");
    }
    CHECK(st == COMM_DONE, "only the offsets step ran, and ended");
    CHECK(c.result_due && c.res.step == PROTO_COMMISSION_STEP_OFFSETS, "its result is due");
    CHECK_NEAR(c.res.value[0], 0.05, 1e-4, "offset a");
    CHECK_NEAR(c.res.value[1], -0.03, 1e-4, "offset b");
    CHECK_NEAR(c.res.value[2], 0.02, 1e-4, "offset c");
    CHECK_NEAR((double)n * 50e-6, 0.22, 0.002, "20 ms settle + 4 x 50 ms");
}

static void test_offset_out_of_range_fails(void)
{
    comm_t c;
    comm_cfg_t k = cfg(1u << PROTO_COMMISSION_STEP_OFFSETS);
    comm_in_t in;
    comm_out_t o;
    uint32_t n;
    uint16_t st = COMM_RUNNING;
    comm_start(&c, &k);
    memset(&in, 0, sizeof(in));
    in.v_dc_v = 540.0f;
    in.i_a_a = 2.0f; /* a broken sensor */
    for (n = 0u; n < 100000u && st == COMM_RUNNING; n++) {
        st = comm_step(&c, &in, &o);
    }
    CHECK(st == COMM_FAILED, "failed");
    CHECK(c.fail_reason == PROTO_COMMISSION_FAIL_IMPLAUSIBLE, "implausible offset");
    CHECK(!o.pwm_on, "PWM off");
}

/* The whole sequence against the plant (a minimal board: sample, step, apply the previous
 * command): planted sensor offsets, encoder offset and dead time come back. */
static void test_sequence_on_the_plant(void)
{
    plant_cfg_t pc;
    plant_t p;
    comm_t c;
    comm_cfg_t k = cfg((uint16_t)((1u << COMM_N_STEPS) - 1u));
    enc_cfg_t ec;
    enc_t e;
    enc_out_t eo;
    fw_cmd_t prev, cmd;
    uint32_t n;
    uint16_t st = COMM_RUNNING, seen = 0u;
    float res[COMM_N_STEPS][4];
    plant_cfg_default(&pc);
    pc.dead_time_s = 2.5e-6;
    pc.v_drop_v = 1.5;
    pc.i_dt_a = 0.5;
    pc.i_offset_a[0] = 0.05;
    pc.i_offset_a[1] = -0.03;
    pc.i_offset_a[2] = 0.02;
    pc.enc_counts = 10000u;
    pc.enc_offset_m_rad = 0.021 / 4.0;
    pc.t_coulomb_nm = 0.05;
    plant_init(&p, &pc);
    ec.counts = 10000u;
    ec.pole_pairs = 4u;
    ec.offset_e_rad = 0.0f;
    ec.bw_rad_s = 1000.0f;
    ec.ts_s = 50e-6f;
    enc_init(&e, &ec);
    comm_start(&c, &k);
    memset(&prev, 0, sizeof(prev));
    memset(res, 0, sizeof(res));
    for (n = 0u; n < 400000u && st == COMM_RUNNING; n++) {
        fw_meas_t m;
        comm_in_t in;
        comm_out_t o;
        plant_sample(&p, &m);
        if (n == 0u) {
            enc_reset(&e, m.enc_count);
        }
        enc_step(&e, m.enc_count, &eo);
        in.i_a_a = m.i_a_a;
        in.i_b_a = m.i_b_a;
        in.i_c_a = m.i_c_a;
        in.v_dc_v = m.v_dc_v;
        in.theta_enc_rad = eo.theta_e_rad;
        in.omega_e_rad_s = eo.omega_e_rad_s;
        st = comm_step(&c, &in, &o);
        if (c.result_due) {
            memcpy(res[c.res.step], c.res.value, sizeof(res[0]));
            seen = (uint16_t)(seen | (1u << c.res.step));
            c.result_due = false;
        }
        memset(&cmd, 0, sizeof(cmd));
        cmd.mode = FW_CMD_DUTIES;
        cmd.duty_a = o.duty[0];
        cmd.duty_b = o.duty[1];
        cmd.duty_c = o.duty[2];
        cmd.pwm_on = o.pwm_on;
        plant_step(&p, &prev);
        prev = cmd;
    }
    CHECK(st == COMM_DONE, "the sequence completed");
    CHECK(seen == (1u << COMM_N_STEPS) - 1u, "every step reported");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_OFFSETS][0], 0.05, 0.005, "offset a");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_OFFSETS][1], -0.03, 0.005, "offset b");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_OFFSETS][2], 0.02, 0.005, "offset c");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_ENCODER][0], -0.021, 0.0035, "encoder offset (0.2 deg)");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_INVERTER][0], 540.0 * 2.5e-6 / 50e-6 + 1.5, 0.05 * 28.5,
               "dead-time plateau");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_R_S][0], 0.9, 0.018, "R");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_L_DQ][0], 0.005, 0.00025, "L_d");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_L_DQ][1], 0.012, 0.0006, "L_q");
    CHECK_NEAR(res[PROTO_COMMISSION_STEP_PSI_F][0], 0.18, 0.0036, "psi_f");
}

int main(void)
{
    test_sequence_on_the_plant();
    test_regression();
    test_inverter_model();
    test_voltage_output();
    test_offsets_step();
    test_offset_out_of_range_fails();
    return CHECK_DONE();
}
