/* Unit tests of the control period's slot interfaces (docs/architecture.md): the current-control
 * slot (cc_slot.h) against its occupant called directly, the angle slot (angle_slot.h), the
 * identification object (ident.h) and the period's event queue (evq.h). */
#include "check.h"

#include <string.h>

#include "cc_slot.h"
#include "angle_slot.h"
#include "ident.h"
#include "evq.h"
#include "rng.h"

static float uni(rng_t *r, float lo, float hi)
{
    return lo + (hi - lo) * (float)rng_uniform(r);
}

static void test_cc_slot(void)
{
    cc_cfg_t cfg;
    cc_t cc;
    mpcc_t twin;
    rng_t r;
    int k;
    bool same = true, states = true;
    uint16_t prev_code = 0u, applied_ok = 1u;
    CHECK(cc_kind_known(CC_KIND_MPCC) && !cc_kind_known(7u),
          "cc: the MPCC is the only occupant known");
    memset(&cfg, 0, sizeof cfg);
    cfg.kind = CC_KIND_MPCC;
    mpcc_cfg_default(&cfg.mpcc);
    cfg.mpcc.dead_time_s = 2e-6f;
    cfg.mpcc.v_drop_v = 1.0f;
    cfg.mpcc.i_dt_a = 0.3f;
    cc_init(&cc, &cfg);
    mpcc_init(&twin, &cfg.mpcc);
    rng_seed(&r, 11u);
    for (k = 0; k < 500; k++) {
        cc_in_t in;
        cc_out_t o;
        mpcc_in_t mi;
        mpcc_out_t mo;
        in.i_d_a = uni(&r, -5.0f, 5.0f);
        in.i_q_a = uni(&r, -5.0f, 5.0f);
        in.i_d_ref_a = uni(&r, -5.0f, 5.0f);
        in.i_q_ref_a = uni(&r, -5.0f, 5.0f);
        in.theta_e_rad = uni(&r, 0.0f, 6.28f);
        in.cos_theta = cosf(in.theta_e_rad);
        in.sin_theta = sinf(in.theta_e_rad);
        in.omega_e_rad_s = uni(&r, -400.0f, 400.0f);
        in.v_dc_v = 540.0f;
        in.pred.r_s_ohm = 0.9f;
        in.pred.l_d_h = 5e-3f;
        in.pred.l_q_h = 12e-3f;
        in.pred.psi_f_wb = 0.18f;
        applied_ok &= (uint16_t)(cc_applied_code(&cc) == prev_code);
        cc_step(&cc, &in, &o);
        mi.i_d_a = in.i_d_a;
        mi.i_q_a = in.i_q_a;
        mi.i_d_ref_a = in.i_d_ref_a;
        mi.i_q_ref_a = in.i_q_ref_a;
        mi.theta_e_rad = in.theta_e_rad;
        mi.omega_e_rad_s = in.omega_e_rad_s;
        mi.v_dc_v = in.v_dc_v;
        mi.r_s_ohm = in.pred.r_s_ohm;
        mi.l_d_h = in.pred.l_d_h;
        mi.l_q_h = in.pred.l_q_h;
        mi.psi_f_wb = in.pred.psi_f_wb;
        mpcc_step_cs(&twin, &mi, in.cos_theta, in.sin_theta, &mo);
        same = same && o.s_a == mo.s_a && o.s_b == mo.s_b && o.s_c == mo.s_c &&
               o.u_d_v == mo.u_d_v && o.u_q_v == mo.u_q_v && o.u_d_avg_v == mo.u_d_avg_v &&
               o.u_q_avg_v == mo.u_q_avg_v && o.i_d_pred_a == mo.i_d_k1_a &&
               o.i_q_pred_a == mo.i_q_k1_a;
        states = states && o.mode == CC_OUT_STATES && o.duty_a == (float)o.s_a &&
                 o.duty_b == (float)o.s_b && o.duty_c == (float)o.s_c;
        prev_code = mo.s_abc_next;
    }
    CHECK(same, "cc: the slot gives exactly what the MPCC gives called directly");
    CHECK(states, "cc: the MPCC's output is switch states (duties 0 or 1 alike)");
    CHECK(applied_ok, "cc: the applied code is the state chosen in the previous period");
    cc_reset(&cc);
    CHECK(cc_applied_code(&cc) == 0u, "cc: reset forgets the applied state");
    cfg.kind = 9u;
    cc_init(&cc, &cfg);
    CHECK(cc.kind == CC_KIND_MPCC, "cc: an unknown kind falls back to the MPCC");
}

static void test_angle_slot(void)
{
    angle_cfg_t cfg;
    angle_t a;
    angle_in_t in;
    angle_out_t o;
    enc_out_t e;
    CHECK(angle_src_known(ANGLE_SRC_ENCODER) && angle_src_known(ANGLE_SRC_RIPPLE_PLL) &&
              angle_src_known(ANGLE_SRC_HYBRID) && !angle_src_known(9u),
          "angle: encoder, MRAS, ripple PLL and hybrid are the sources known");
    memset(&cfg, 0, sizeof cfg);
    cfg.src = ANGLE_SRC_RIPPLE_PLL; /* without its configuration */
    cfg.pole_pairs = 4u;
    cfg.ts_s = 50e-6f;
    angle_init(&a, &cfg);
    CHECK(a.cfg.src == ANGLE_SRC_ENCODER,
          "angle: the ripple PLL without its configuration falls back to the encoder");
    cfg.src = 9u;
    cfg.pole_pairs = 4u;
    cfg.ts_s = 50e-6f;
    angle_init(&a, &cfg);
    CHECK(a.cfg.src == ANGLE_SRC_ENCODER, "angle: an unknown source falls back to the encoder");
    memset(&in, 0, sizeof in);
    memset(&e, 0, sizeof e);
    e.theta_e_rad = 1.25f;
    e.omega_e_rad_s = 100.0f;
    e.omega_m_rad_s = 25.0f;
    e.speed_rpm = 238.7f;
    in.enc = &e;
    angle_step(&a, &in, &o);
    CHECK(o.valid && o.theta_e_rad == 1.25f && o.omega_e_rad_s == 100.0f &&
              o.omega_m_rad_s == 25.0f && o.speed_rpm == 238.7f,
          "angle: the encoder occupant passes the encoder's reading on");
    in.enc = NULL;
    angle_step(&a, &in, &o);
    CHECK(!o.valid && o.speed_rpm == 0.0f,
          "angle: without an encoder the encoder occupant is not valid");
}

static void ident_cfg(ident_cfg_t *c)
{
    memset(c, 0, sizeof *c);
    c->nominal.r_s_ohm = 0.9f;
    c->nominal.l_d_h = 5e-3f;
    c->nominal.l_q_h = 12e-3f;
    c->nominal.psi_f_wb = 0.18f;
    c->pred_scale.r_s_ohm = 1.0f;
    c->pred_scale.l_d_h = 0.5f;
    c->pred_scale.l_q_h = 2.0f;
    c->pred_scale.psi_f_wb = 1.0f;
    c->pole_pairs = 4u;
    c->ts_s = 50e-6f;
    c->id_window = 20u;
}

static void test_ident(void)
{
    ident_cfg_t cfg;
    ident_t id;
    ident_seg_t seg;
    ident_in_t in;
    ident_out_t o;
    cc_params_t p;
    est_out_t rep;
    uint16_t k;
    uint32_t t, events = 0u;
    float r_event = 0.0f, r_during = 0.0f;
    bool ops_ok = true;

    ident_cfg(&cfg);
    ident_init(&id, &cfg);
    for (k = 0u; k < IDENT_N_EST; k++) {
        ops_ok = ops_ok && id.ops[k] != NULL && id.est[k] != NULL && id.ops[k]->init != NULL &&
                 id.ops[k]->set_r != NULL && id.ops[k]->step != NULL;
    }
    CHECK(ops_ok, "ident: every estimator sits behind a full operations table");
    ident_predictor(&id, &p);
    CHECK(p.r_s_ohm == 0.9f && p.l_d_h == 2.5e-3f && p.l_q_h == 24e-3f && p.psi_f_wb == 0.18f &&
              ident_nominal_feeds(&id),
          "ident: identification off, the predictor gets nominal x scale");

    memset(&seg, 0, sizeof seg);
    seg.inject_a = 2.0f;
    seg.inject_hz = 100.0f; /* 200 periods per excitation period */
    seg.tick = 50u;
    CHECK(ident_d_ref(&id, &seg, -1.0f) == 1.0f,
          "ident: first half of the excitation is base + amplitude");
    seg.tick = 150u;
    CHECK(ident_d_ref(&id, &seg, -1.0f) == -3.0f, "ident: second half is base - amplitude");
    seg.identify_r = true;
    seg.inject_a = 4.0f;
    seg.ticks = 2000u;
    seg.tick = 999u;
    CHECK(ident_d_ref(&id, &seg, -1.0f) == 4.0f, "ident: identify_r, first half at inject_a");
    seg.tick = 1000u;
    CHECK(ident_d_ref(&id, &seg, -1.0f) == 2.0f, "ident: identify_r, second half at inject_a / 2");

    /* the R injection: steady d currents on two levels, u = R i with R = 0.6 ohm */
    cfg.identify = true;
    cfg.predictor = 1u;
    cfg.have_injection = true;
    ident_init(&id, &cfg);
    ident_report(&id, 0u, &rep);
    CHECK(rep.r_s_ohm == 0.0f, "ident: before the injection, R is reported as unknown (0)");
    memset(&in, 0, sizeof in);
    for (t = 0u; t < seg.ticks; t++) {
        seg.tick = t;
        in.i_d_a = ident_d_ref(&id, &seg, 0.0f);
        in.i_q_a = 0.0f;
        in.u_d_avg_v = 0.6f * in.i_d_a;
        in.u_q_avg_v = 0.0f;
        in.i_a_a = in.i_d_a;
        in.i_b_a = -0.5f * in.i_d_a;
        in.i_c_a = -0.5f * in.i_d_a;
        in.i_d_ref_a = in.i_d_a;
        ident_step(&id, &seg, &in, &o);
        if (o.r_identified_now) {
            events++;
            r_event = o.r_s_ohm;
        }
        if (t == seg.ticks / 2u) {
            ident_report(&id, 1u, &rep);
            r_during = rep.r_s_ohm;
        }
    }
    CHECK(events == 1u, "ident: R identified once, at the end of the segment");
    CHECK_NEAR(r_event, 0.6f, 1e-3, "ident: the injection finds R");
    CHECK_NEAR(r_during, 0.6f, 1e-3, "ident: while it runs, the injection's running R is reported");
    ident_predictor(&id, &p);
    CHECK(p.r_s_ohm == r_event && p.l_d_h == 2.5e-3f,
          "ident: the predictor takes the identified R, nominal L until convergence");
    ident_report(&id, 2u, &rep);
    CHECK(rep.r_s_ohm == r_event, "ident: every estimator starts from the identified R");
    CHECK(ident_nominal_feeds(&id), "ident: no estimator feeds the predictor before it converged");
}

static void test_evq(void)
{
    evq_t q;
    uint16_t i;
    bool ok = true;
    evq_init(&q);
    CHECK(evq_count(&q) == 0u && evq_at(&q, 0u) == NULL, "evq: empty");
    for (i = 0u; i < EVQ_LEN + 3u; i++) {
        (void)evq_push(&q, 100u + i, (uint16_t)(i + 1u), -(int32_t)i);
    }
    CHECK(evq_count(&q) == EVQ_LEN && q.lost == 3u,
          "evq: a full queue keeps the first and counts the rest");
    for (i = 0u; i < EVQ_LEN; i++) {
        const evq_entry_t *e = evq_at(&q, i);
        ok = ok && e->tick == 100u + i && e->code == i + 1u && e->arg == -(int32_t)i;
    }
    CHECK(ok, "evq: events in the order raised, each with its tick");
    evq_clear(&q);
    CHECK(evq_count(&q) == 0u && q.lost == 3u, "evq: cleared after sending (the loss count stays)");
}

int main(void)
{
    test_cc_slot();
    test_angle_slot();
    test_ident();
    test_evq();
    return CHECK_DONE();
}
