/* The emulator's C API: the firmware core on the sim board (plant + virtual UART), loaded by
 * pmsm_hil.emulator.fwlib with ctypes. All time is device time: a call to emu_run advances the
 * control ISR by whole periods while the firmware is active, and drains the UART at its bit rate. */
#ifndef EMU_H
#define EMU_H

#include <stddef.h>
#include <stdint.h>

typedef struct emu emu_t;

size_t emu_size(void);
void emu_init(emu_t *e);                              /* defaults: paper A motor, ideal sensors */
int emu_set(emu_t *e, const char *key, double value); /* 0, or -1 for an unknown key */
int emu_get(const emu_t *e, const char *key, double *value);
void emu_reset(emu_t *e); /* applies the settings: firmware and plant anew */
void emu_rx(emu_t *e, const uint8_t *data, uint32_t n); /* octets from the host */
/* Runs at most max_ticks control periods (none while the firmware is idle) and writes the octets
 * the UART sent meanwhile into out (at most cap); returns the periods run, *n_out the octets. */
uint32_t emu_run(emu_t *e, uint32_t max_ticks, uint8_t *out, uint32_t cap, uint32_t *n_out);
uint32_t emu_isr_count(const emu_t *e);
uint32_t emu_heartbeat_isr(const emu_t *e);
/* The heartbeat timeout and control period the firmware accepted (its config_ctrl; fuzz targets) */
void emu_heartbeat_cfg(const emu_t *e, double *timeout_s, double *ts_s);
/* isr count at the last change of the firmware's state (seen after the control period that made
 * it), and in *hb_isr the isr count of the last heartbeat at that moment */
uint32_t emu_state_change(const emu_t *e, uint32_t *hb_isr);
int emu_state(const emu_t *e);
int emu_active(const emu_t *e);
/* Rig effects: array settings (the saturation flux map: "sat_psi_d_wb", "sat_psi_q_wb", nodes with
 * i_d fastest; 0, or -1 for an unknown key or too many values), applied by emu_reset. */
int emu_set_array(emu_t *e, const char *key, const double *values, uint32_t n);
/* NULL when the settings applied by the last emu_reset are usable, else a message. */
const char *emu_check(const emu_t *e);
/* The plant's magnetics at a point (tests): psi_d, psi_q, L_dd, L_dq, L_qd, L_qq, extra torque, torque. */
void emu_plant_flux(const emu_t *e, double i_d_a, double i_q_a, double theta_e_rad, double out[8]);
/* The plant's truth now (tests): fills out[0 .. n-1] in the order of EMU_TRUTH (emu_table.h) and
 * returns how many values there are. */
int emu_plant_truth(const emu_t *e, double *out, int n);
/* The names of the settings (emu_set keys) and of the truth values, in table order (emu_table.h);
 * NULL past the end. */
const char *emu_setting_name(uint32_t i);
const char *emu_truth_name(uint32_t i);
/* The build's identity: the SHA-256 (first 16 hex digits) of the firmware core's and the sim
 * board's sources it was compiled from (setup.py defines EMU_SOURCE_SHA256), "unknown" in a
 * build without it. Two builds of the same sources give the same device data. */
const char *emu_source_id(void);
/* CAN (docs/can.md; settings can_bitrate, can_node): a frame from the host, and the frames the
 * sim board's controller sent during emu_run, at most cap: ids, dlc, data (8 octets per frame),
 * isr (control period at the end of the frame); returns how many. */
void emu_can_rx(emu_t *e, uint32_t id, const uint8_t *data, uint32_t dlc);
uint32_t emu_can_take(emu_t *e, uint32_t *ids, uint8_t *dlc, uint8_t *data, uint32_t *isr,
                      uint32_t cap);

/* Continuous control-rate recording (simulation only): from now on every control period appends one
 * row of EMU_REC_COLS values to buf (at most cap rows): t_s, i_a_a, i_b_a, i_c_a (as measured),
 * s_a, s_b, s_c, pwm_on (the command applied over the period), v_dc_v (measured), theta_e_rad,
 * omega_e_rad_s (the firmware's encoder angle and speed), load_nm. NULL stops it. */
#define EMU_REC_COLS 12
void emu_record(emu_t *e, double *buf, uint32_t cap);
uint32_t emu_record_count(const emu_t *e);

#endif
