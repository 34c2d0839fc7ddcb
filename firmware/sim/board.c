/* The sim board: adapts the plant to the firmware core as the F28335 board adapts the hardware.
 * Per control period: sample (ADC, encoder) -> firmware ISR -> the plant runs one period with the
 * command computed in the previous period (the DSP's one-period computation delay). */
#include "emu.h"

#include <string.h>

#include "fw.h"
#include "plant.h"

struct emu {
    fw_t fw;
    plant_t plant;
    plant_cfg_t pcfg;
    fw_cmd_t prev_cmd;
    double baud;
    double octet_budget;
    uint32_t truth_div;
    uint32_t truth_count;
    int was_active;
    uint16_t payload[PROTO_MAX_PAYLOAD + 4u];
};

size_t emu_size(void) { return sizeof(emu_t); }

void emu_init(emu_t *e)
{
    memset(e, 0, sizeof(*e));
    plant_cfg_default(&e->pcfg);   /* paper A's IPMSM, 540 V DC link, ideal inverter and sensors */
    e->baud = 921600.0;
    e->truth_div = 200u;
    emu_reset(e);
}

#define EMU_KEY(name, field, type) \
    if (strcmp(key, name) == 0) { e->field = (type)value; return 0; }

int emu_set(emu_t *e, const char *key, double value)
{
    EMU_KEY("r_s_ohm", pcfg.r_s_ohm, double)
    EMU_KEY("l_d_h", pcfg.l_d_h, double)
    EMU_KEY("l_q_h", pcfg.l_q_h, double)
    EMU_KEY("psi_f_wb", pcfg.psi_f_wb, double)
    EMU_KEY("pole_pairs", pcfg.pole_pairs, int)
    EMU_KEY("j_kgm2", pcfg.j_kgm2, double)
    EMU_KEY("b_visc_nms", pcfg.b_visc_nms, double)
    EMU_KEY("t_coulomb_nm", pcfg.t_coulomb_nm, double)
    EMU_KEY("v_dc_v", pcfg.v_dc_v, double)
    EMU_KEY("dead_time_s", pcfg.dead_time_s, double)
    EMU_KEY("v_drop_v", pcfg.v_drop_v, double)
    EMU_KEY("i_dt_a", pcfg.i_dt_a, double)
    EMU_KEY("i_noise_a", pcfg.i_noise_a, double)
    EMU_KEY("adc_lsb_a", pcfg.adc_lsb_a, double)
    EMU_KEY("enc_counts", pcfg.enc_counts, uint32_t)
    EMU_KEY("enc_offset_rad", pcfg.enc_offset_rad, double)
    EMU_KEY("ts_s", pcfg.ts_s, double)
    EMU_KEY("substeps", pcfg.substeps, int)
    EMU_KEY("seed", pcfg.seed, uint32_t)
    EMU_KEY("temp_ambient_c", pcfg.temp_ambient_c, double)
    EMU_KEY("baud", baud, double)
    EMU_KEY("truth_div", truth_div, uint32_t)
    return -1;
}

int emu_get(const emu_t *e, const char *key, double *value)
{
    if (strcmp(key, "ts_s") == 0) { *value = e->pcfg.ts_s; return 0; }
    if (strcmp(key, "baud") == 0) { *value = e->baud; return 0; }
    if (strcmp(key, "seed") == 0) { *value = (double)e->pcfg.seed; return 0; }
    if (strcmp(key, "tick") == 0) { *value = (double)e->fw.tick; return 0; }
    if (strcmp(key, "tx_dropped") == 0) { *value = (double)e->fw.tx.dropped; return 0; }
    if (strcmp(key, "tx_level") == 0) { *value = (double)e->fw.tx.level; return 0; }
    if (strcmp(key, "heartbeat_timeout_s") == 0) {
        *value = e->fw.have_ctrl ? (double)e->fw.ctrl.heartbeat_timeout_s : 0.0;
        return 0;
    }
    return -1;
}

void emu_reset(emu_t *e)
{
    fw_cfg_t cfg;
    cfg.board = FW_BOARD_SIM;
    fw_init(&e->fw, &cfg);
    plant_init(&e->plant, &e->pcfg);
    memset(&e->prev_cmd, 0, sizeof(e->prev_cmd));
    e->octet_budget = 0.0;
    e->truth_count = 0u;
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
    m.tick = e->fw.tick;
    m.l_d_h = (float)t.l_d_h;
    m.l_q_h = (float)t.l_q_h;
    m.psi_f_wb = (float)t.psi_f_wb;
    m.r_s_ohm = (float)t.r_s_ohm;
    m.theta_e_rad = (float)t.theta_e_rad;
    m.speed_rpm = (float)t.speed_rpm;
    m.torque_nm = (float)t.torque_nm;
    m.temp_winding_c = (float)t.temp_winding_c;
    m.temp_magnet_c = (float)t.temp_magnet_c;
    m.effects = 0u;
    n = proto_sim_truth_pack(&m, e->payload);
    (void)fw_send(&e->fw, PROTO_ID_SIM_TRUTH, e->payload, n);
}

static uint32_t drain(emu_t *e, uint8_t *out, uint32_t cap, uint32_t n, uint32_t limit)
{
    uint16_t buf[64];
    while (n < cap && limit > 0u) {
        uint32_t want = cap - n;
        uint16_t got, i;
        if (want > limit) { want = limit; }
        if (want > 64u) { want = 64u; }
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
        e->pcfg.ts_s = (double)e->fw.ctrl.ts_s;
        per_tick = e->baud / 10.0 * e->pcfg.ts_s;
        margin = (uint32_t)per_tick + 2u;
        plant_init(&e->plant, &e->pcfg);
        memset(&e->prev_cmd, 0, sizeof(e->prev_cmd));
        e->octet_budget = 0.0;
        e->truth_count = 0u;
    }
    while (ticks < max_ticks && fw_active(&e->fw) && n + margin <= cap) {
        e->was_active = 1;
        plant_sample(&e->plant, &meas);
        if (e->truth_div != 0u && e->truth_count == 0u) {
            send_truth(e);
        }
        fw_isr(&e->fw, &meas, &cmd);
        plant_step(&e->plant, &e->prev_cmd);
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
                e->octet_budget = 0.0;  /* the line was idle: no credit carries over */
            }
        }
        ticks++;
    }
    if (!fw_active(&e->fw)) {
        /* idle link: whatever is queued leaves now */
        e->was_active = 0;
        n = drain(e, out, cap, n, 0xFFFFFFFFu);
    }
    *n_out = n;
    return ticks;
}

uint32_t emu_isr_count(const emu_t *e) { return e->fw.isr_count; }
uint32_t emu_heartbeat_isr(const emu_t *e) { return e->fw.hb_isr; }
int emu_state(const emu_t *e) { return (int)e->fw.state; }
int emu_active(const emu_t *e) { return fw_active(&e->fw) ? 1 : 0; }
