/* The sim board: adapts the plant to the firmware core as the F28335 board adapts the hardware.
 * Per control period: sample (ADC, encoder) -> firmware ISR -> the plant runs one period with the
 * command computed in the previous period (the DSP's one-period computation delay). */
#include "emu.h"

#include <string.h>

#include "fw.h"
#include "plant.h"
#include "can_bus_sim.h"
#include "emu_table.h"

struct emu {
    fw_t fw;
    plant_t plant;
    plant_cfg_t pcfg;
    fw_cmd_t prev_cmd;
    double baud;
    double can_bitrate; /* docs/can.md */
    uint16_t can_node;
    can_sim_t can;
    double octet_budget;
    double truth_hz;    /* sim_truth frames per second of device time (0: none) */
    uint32_t truth_div; /* ... as control periods, set at a run's start from the firmware's ts */
    uint32_t truth_count;
    int was_active;
    uint16_t payload[PROTO_MAX_PAYLOAD + 4u];
    /* sim_plant: per segment, a step of the true R and psi_f at the segment start (drift tests) */
    float plant_r_scale[PROFILE_MAX_SEGMENTS];
    float plant_psi_scale[PROFILE_MAX_SEGMENTS];
    uint64_t plant_step_mask;
    int plant_seg; /* segment whose start was last looked at, -1 before the first */
    /* the last change of the firmware's state, seen after each control period (emu_state_change) */
    int last_state;
    uint32_t state_isr, state_hb_isr;
    /* rig effects (docs/rigs.md): the mask reported in sim_truth, and the saturation flux map */
    uint32_t effects_mask;
    /* wiring faults of the rig (commissioning tests): phases b and c swapped between inverter
     * and motor, or the motor not connected */
    int wiring_swap_bc, wiring_open;
    double theta_e0_rad; /* the rotor's electrical angle at the start of a run (sensorless tests) */
    int sat_nd, sat_nq;  /* 0: no map */
    double sat_id0_a, sat_did_a, sat_iq0_a, sat_diq_a;
    double sat_psi_d_wb[PLANT_MAP_MAX_N * PLANT_MAP_MAX_N];
    double sat_psi_q_wb[PLANT_MAP_MAX_N * PLANT_MAP_MAX_N];
    plant_map_t map;
    /* continuous control-rate recording (simulation only; emu_record): EMU_REC_COLS per period */
    double *rec;
    uint32_t rec_cap, rec_n;
};

/* Board hook: sim-only h2d messages (fw.c passes the ones it does not know). */
static uint16_t board_msg(void *ctx, uint16_t msg_id, const uint16_t *payload, uint16_t n)
{
    emu_t *e = (emu_t *)ctx;
    if (msg_id == PROTO_ID_SIM_PLANT) {
        proto_sim_plant_t m;
        if (!proto_sim_plant_unpack(&m, payload, n) || m.index >= PROFILE_MAX_SEGMENTS ||
            !(m.r_s_scale > 0.0f && m.r_s_scale < 10.0f) ||
            !(m.psi_f_scale > 0.0f && m.psi_f_scale < 10.0f)) {
            return PROTO_ACK_STATUS_BAD_VALUE;
        }
        if (fw_active(&e->fw)) {
            return PROTO_ACK_STATUS_BUSY;
        }
        e->plant_r_scale[m.index] = m.r_s_scale;
        e->plant_psi_scale[m.index] = m.psi_f_scale;
        e->plant_step_mask |= (uint64_t)1u << m.index;
        return PROTO_ACK_STATUS_OK;
    }
    return PROTO_ACK_STATUS_UNKNOWN;
}

/* Apply a sim_plant step when its segment starts (after the firmware's ISR of that period). */
static void plant_steps(emu_t *e)
{
    bool begun;
    const int seg = (int)fw_segment(&e->fw, &begun);
    if (seg != e->plant_seg && begun) {
        e->plant_seg = seg;
        if (seg < (int)PROFILE_MAX_SEGMENTS && ((e->plant_step_mask >> seg) & 1u) != 0u) {
            plant_set_param_scale(&e->plant, &e->pcfg, (double)e->plant_r_scale[seg],
                                  (double)e->plant_psi_scale[seg]);
        }
    }
}

size_t emu_size(void)
{
    return sizeof(emu_t);
}

void emu_init(emu_t *e)
{
    memset(e, 0, sizeof(*e));
    plant_cfg_default(&e->pcfg); /* paper A's IPMSM, 540 V DC link, ideal inverter and sensors */
    e->baud = 921600.0;
    e->can_bitrate = (double)PROTO_CAN_BITRATE;
    e->can_node = PROTO_CAN_NODE_DEFAULT;
    e->truth_hz = 100.0;
    emu_reset(e);
}

#define EMU_SET(key, member, type)                                                                 \
    if (strcmp(name, #key) == 0) {                                                                 \
        e->member = (type)value;                                                                   \
        return 0;                                                                                  \
    }

int emu_set(emu_t *e, const char *name, double value)
{
    EMU_SETTINGS(EMU_SET)
    return -1;
}

int emu_get(const emu_t *e, const char *key, double *value)
{
    if (strcmp(key, "ts_s") == 0) {
        *value = e->pcfg.ts_s;
        return 0;
    }
    if (strcmp(key, "baud") == 0) {
        *value = e->baud;
        return 0;
    }
    if (strcmp(key, "seed") == 0) {
        *value = (double)e->pcfg.seed;
        return 0;
    }
    if (strcmp(key, "tick") == 0) {
        *value = (double)fw_tick(&e->fw);
        return 0;
    }
    if (strcmp(key, "tx_dropped") == 0) {
        *value = (double)fw_tx_dropped(&e->fw);
        return 0;
    }
    if (strcmp(key, "tx_level") == 0) {
        *value = (double)fw_tx_level(&e->fw);
        return 0;
    }
    if (strcmp(key, "can_bits") == 0) {
        *value = e->can.bits_sent;
        return 0;
    }
    if (strcmp(key, "can_frames") == 0) {
        *value = (double)e->can.frames_sent;
        return 0;
    }
    if (strcmp(key, "can_level") == 0) {
        *value = (double)fw_can_tx_level(&e->fw);
        return 0;
    }
    if (strcmp(key, "heartbeat_timeout_s") == 0) {
        const proto_config_ctrl_t *c = fw_ctrl(&e->fw);
        *value = c != NULL ? (double)c->heartbeat_timeout_s : 0.0;
        return 0;
    }
    return -1;
}

/* Control periods between sim_truth frames for truth_hz at ts_s (0: no frames). */
static uint32_t truth_periods(double truth_hz, double ts_s)
{
    double n;
    if (!(truth_hz > 0.0) || !(ts_s > 0.0)) {
        return 0u;
    }
    n = 1.0 / (truth_hz * ts_s) + 0.5;
    return n < 1.0 ? 1u : (n > 4.0e9 ? 4000000000u : (uint32_t)n);
}

void emu_reset(emu_t *e)
{
    fw_cfg_t cfg;
    cfg.board = PROTO_BOARD_EMULATOR;
    cfg.can_node = e->can_node;
    fw_init(&e->fw, &cfg);
    can_sim_init(&e->can, e->can_bitrate);
    fw_set_board_hook(&e->fw, board_msg, e);
    e->last_state = (int)fw_state(&e->fw);
    e->state_isr = e->state_hb_isr = 0u;
    e->plant_step_mask = 0u;
    e->plant_seg = -1;
    e->pcfg.map = NULL; /* saturation: the flux map given by emu_set_array, if any */
    if (e->sat_nd > 0 && e->sat_nq > 0 &&
        plant_map_build(&e->map, e->sat_nd, e->sat_nq, e->sat_id0_a, e->sat_did_a, e->sat_iq0_a,
                        e->sat_diq_a, e->sat_psi_d_wb, e->sat_psi_q_wb) == NULL) {
        e->pcfg.map = &e->map;
    }
    plant_init(&e->plant, &e->pcfg);
    memset(&e->prev_cmd, 0, sizeof(e->prev_cmd));
    e->octet_budget = 0.0;
    e->truth_count = 0u;
    e->truth_div = truth_periods(e->truth_hz, e->pcfg.ts_s);
    e->was_active = 0;
}

void emu_rx(emu_t *e, const uint8_t *data, uint32_t n)
{
    uint32_t i;
    for (i = 0u; i < n; i++) {
        fw_rx_octet(&e->fw, (uint16_t)data[i]);
    }
}

static void send_truth(emu_t *e)
{
    plant_truth_t t;
    proto_sim_truth_t m;
    uint16_t n;
    plant_truth(&e->plant, &t);
    m.tick = fw_tick(&e->fw);
    m.l_d_h = (float)t.l_d_h;
    m.l_q_h = (float)t.l_q_h;
    m.psi_f_wb = (float)t.psi_f_wb;
    m.r_s_ohm = (float)t.r_s_ohm;
    m.theta_e_rad = (float)t.theta_e_rad;
    m.speed_rpm = (float)t.speed_rpm;
    m.torque_nm = (float)t.torque_nm;
    m.temp_winding_c = (float)t.temp_winding_c;
    m.temp_magnet_c = (float)t.temp_magnet_c;
    m.effects = e->effects_mask;
    m.l_d_secant_h = (float)t.l_d_secant_h;
    m.l_q_secant_h = (float)t.l_q_secant_h;
    n = proto_sim_truth_pack(&m, e->payload);
    (void)fw_send(&e->fw, PROTO_ID_SIM_TRUTH, e->payload, n);
}

static uint32_t drain(emu_t *e, uint8_t *out, uint32_t cap, uint32_t n, uint32_t limit)
{
    uint16_t buf[64];
    while (n < cap && limit > 0u) {
        uint32_t want = cap - n;
        uint16_t got, i;
        if (want > limit) {
            want = limit;
        }
        if (want > 64u) {
            want = 64u;
        }
        got = fw_tx_pop_n(&e->fw, buf, (uint16_t)want);
        for (i = 0u; i < got; i++) {
            out[n++] = (uint8_t)buf[i];
        }
        limit -= got;
        if (got < want) {
            break;
        }
    }
    return n;
}

/* One row of the continuous recording: what the firmware measured at the period start and the
 * command the board applies over this period (the previous one: one-period computation delay). */
static void record_period(emu_t *e, const fw_meas_t *m)
{
    double *r = e->rec + (size_t)e->rec_n * EMU_REC_COLS;
    r[0] = ((double)e->fw.tick - 1.0) *
           e->pcfg.ts_s; /* the ISR has counted this period: as /pmsm/capture labels it */
    r[1] = (double)m->i_a_a;
    r[2] = (double)m->i_b_a;
    r[3] = (double)m->i_c_a;
    r[4] = (double)e->prev_cmd.s_a;
    r[5] = (double)e->prev_cmd.s_b;
    r[6] = (double)e->prev_cmd.s_c;
    r[7] = e->prev_cmd.pwm_on ? 1.0 : 0.0;
    r[8] = (double)m->v_dc_v;
    r[9] = (double)e->fw.sig.theta_e_rad;
    r[10] = (double)e->fw.sig.omega_e_rad_s;
    r[11] = (double)e->prev_cmd.load_nm;
    e->rec_n++;
}

void emu_record(emu_t *e, double *buf, uint32_t cap)
{
    e->rec = buf;
    e->rec_cap = buf != NULL ? cap : 0u;
    e->rec_n = 0u;
}

uint32_t emu_record_count(const emu_t *e)
{
    return e->rec_n;
}

uint32_t emu_run(emu_t *e, uint32_t max_ticks, uint8_t *out, uint32_t cap, uint32_t *n_out)
{
    uint32_t ticks = 0u, n = 0u;
    double per_tick = e->baud / 10.0 * e->pcfg.ts_s;
    uint32_t margin = (uint32_t)per_tick + 2u;
    fw_meas_t meas;
    fw_cmd_t cmd;

    if (fw_active(&e->fw) && !e->was_active) {
        /* a new run: the rig starts from rest, with its noise sequence from the seed, and the
         * PWM period the firmware configured (as the F28335 board sets its PWM timer) */
        e->pcfg.ts_s = (double)fw_ctrl(&e->fw)->ts_s;
        per_tick = e->baud / 10.0 * e->pcfg.ts_s;
        e->truth_div = truth_periods(e->truth_hz, e->pcfg.ts_s);
        margin = (uint32_t)per_tick + 2u;
        plant_init(&e->plant, &e->pcfg);
        if (e->theta_e0_rad != 0.0) {
            plant_set_mech(&e->plant, e->theta_e0_rad / (double)e->pcfg.pole_pairs, 0.0, false);
        }
        memset(&e->prev_cmd, 0, sizeof(e->prev_cmd));
        e->octet_budget = 0.0;
        e->truth_count = 0u;
        e->plant_seg = -1;
    }
    while (ticks < max_ticks && fw_active(&e->fw) && n + margin <= cap && can_sim_room(&e->can)) {
        e->was_active = 1;
        plant_sample(&e->plant, &meas);
        if (e->wiring_swap_bc) { /* the sensor on leg b measures motor phase c */
            float t = meas.i_b_a;
            meas.i_b_a = meas.i_c_a;
            meas.i_c_a = t;
        }
        if (e->truth_div != 0u && e->truth_count == 0u) {
            send_truth(e);
        }
        fw_isr(&e->fw, &meas, &cmd);
        if ((int)fw_state(&e->fw) != e->last_state) {
            e->last_state = (int)fw_state(&e->fw);
            e->state_isr = fw_isr_count(&e->fw);
            e->state_hb_isr = fw_heartbeat_isr(&e->fw);
        }
        if (e->rec != NULL && e->rec_n < e->rec_cap) {
            record_period(e, &meas);
        }
        plant_steps(e);
        if (e->wiring_swap_bc || e->wiring_open) {
            fw_cmd_t w = e->prev_cmd;
            if (e->wiring_swap_bc) { /* leg b drives motor phase c */
                w.s_b = e->prev_cmd.s_c;
                w.s_c = e->prev_cmd.s_b;
                w.duty_b = e->prev_cmd.duty_c;
                w.duty_c = e->prev_cmd.duty_b;
            }
            if (e->wiring_open) {
                w.pwm_on = false;
            }
            plant_step(&e->plant, &w);
        } else {
            plant_step(&e->plant, &e->prev_cmd); /* switch states or duties (plant_step_duty) */
        }
        e->prev_cmd = cmd;
        e->truth_count++;
        if (e->truth_count >= e->truth_div) {
            e->truth_count = 0u;
        }
        e->octet_budget += per_tick;
        if (e->octet_budget >= 1.0) {
            uint32_t k = (uint32_t)e->octet_budget;
            uint32_t before = n;
            n = drain(e, out, cap, n, k);
            e->octet_budget -= (double)k;
            if (n - before < k) {
                e->octet_budget = 0.0; /* the line was idle: no credit carries over */
            }
        }
        can_sim_period(&e->can, &e->fw, e->pcfg.ts_s);
        ticks++;
    }
    if (!fw_active(&e->fw)) {
        /* idle link: whatever is queued leaves now */
        if (e->was_active) {
            e->plant_step_mask = 0u; /* sim_plant steps belong to the run that ended */
        }
        e->was_active = 0;
        n = drain(e, out, cap, n, 0xFFFFFFFFu);
        can_sim_flush(&e->can, &e->fw);
    }
    *n_out = n;
    return ticks;
}

uint32_t emu_isr_count(const emu_t *e)
{
    return fw_isr_count(&e->fw);
}
uint32_t emu_heartbeat_isr(const emu_t *e)
{
    return fw_heartbeat_isr(&e->fw);
}

void emu_heartbeat_cfg(const emu_t *e, double *timeout_s, double *ts_s)
{
    *timeout_s = (double)e->fw.ctrl.heartbeat_timeout_s;
    *ts_s = (double)e->fw.ctrl.ts_s;
}
int emu_state(const emu_t *e)
{
    return (int)fw_state(&e->fw);
}
uint32_t emu_state_change(const emu_t *e, uint32_t *hb_isr)
{
    *hb_isr = e->state_hb_isr;
    return e->state_isr;
}
int emu_active(const emu_t *e)
{
    return fw_active(&e->fw) ? 1 : 0;
}

/* CAN (docs/can.md): a frame from the host; the frames the controller sent (see can_sim_take). */
void emu_can_rx(emu_t *e, uint32_t id, const uint8_t *data, uint32_t dlc)
{
    uint16_t d[8] = { 0 }, k;
    for (k = 0u; k < 8u && k < dlc; k++) {
        d[k] = data[k];
    }
    fw_can_rx(&e->fw, (uint16_t)id, d, (uint16_t)(dlc > 8u ? 8u : dlc));
}

uint32_t emu_can_take(emu_t *e, uint32_t *ids, uint8_t *dlc, uint8_t *data, uint32_t *isr,
                      uint32_t cap)
{
    return can_sim_take(&e->can, ids, dlc, data, isr, cap);
}

int emu_set_array(emu_t *e, const char *key, const double *values, uint32_t n)
{
    double *dst = NULL;
    uint32_t i;
    if (strcmp(key, "sat_psi_d_wb") == 0) {
        dst = e->sat_psi_d_wb;
    } else if (strcmp(key, "sat_psi_q_wb") == 0) {
        dst = e->sat_psi_q_wb;
    }
    if (dst == NULL || n > (uint32_t)(PLANT_MAP_MAX_N * PLANT_MAP_MAX_N)) {
        return -1;
    }
    for (i = 0u; i < n; i++) {
        dst[i] = values[i];
    }
    return 0;
}

#ifndef EMU_SOURCE_SHA256
#define EMU_SOURCE_SHA256 "unknown"
#endif

const char *emu_source_id(void)
{
    return EMU_SOURCE_SHA256;
}

const char *emu_check(const emu_t *e)
{
    if (e->sat_nd > 0 && e->pcfg.map == NULL) {
        return "saturation: the flux map could not be built (grid size or values)";
    }
    return plant_cfg_check(&e->pcfg);
}

void emu_plant_flux(const emu_t *e, double i_d_a, double i_q_a, double theta_e_rad, double out[8])
{
    plant_mag_t m;
    plant_flux(&e->plant, i_d_a, i_q_a, theta_e_rad, &m);
    out[0] = m.psi_d_wb;
    out[1] = m.psi_q_wb;
    out[2] = m.l_dd;
    out[3] = m.l_dq;
    out[4] = m.l_qd;
    out[5] = m.l_qq;
    out[6] = m.t_extra_nm;
    out[7] = plant_torque(&e->plant, i_d_a, i_q_a, theta_e_rad);
}

#define EMU_TRUTH_NAME(key, expr)           #key,
#define EMU_TRUTH_VALUE(key, expr)          expr,
#define EMU_SETTING_NAME(key, member, type) #key,

static const char *const k_truth_names[] = { EMU_TRUTH(EMU_TRUTH_NAME) };
static const char *const k_setting_names[] = { EMU_SETTINGS(EMU_SETTING_NAME) };

const char *emu_truth_name(uint32_t i)
{
    return i < sizeof k_truth_names / sizeof k_truth_names[0] ? k_truth_names[i] : NULL;
}

const char *emu_setting_name(uint32_t i)
{
    return i < sizeof k_setting_names / sizeof k_setting_names[0] ? k_setting_names[i] : NULL;
}

int emu_plant_truth(const emu_t *e, double *out, int n)
{
    plant_truth_t t;
    int i, m;
    plant_truth(&e->plant, &t);
    {
        const double w[] = { EMU_TRUTH(EMU_TRUTH_VALUE) };
        m = (int)(sizeof w / sizeof w[0]);
        for (i = 0; i < n && i < m; i++) {
            out[i] = w[i];
        }
    }
    return m;
}
