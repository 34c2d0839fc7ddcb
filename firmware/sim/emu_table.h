/* The sim board's settings and the order of the plant truth: one table each, used by the board
 * (firmware/sim/board.c: emu_set, emu_plant_truth) and, through emu_setting_name and
 * emu_truth_name, by the Python side (pmsm_hil.emulator.fwlib SETTING_KEYS, TRUTH_KEYS; the
 * settings that pmsm_hil.emulator.settings builds are checked against it).
 *   EMU_SETTINGS(X): X(key, member of emu_t, C type)
 *   EMU_TRUTH(X):    X(key, expression over plant_truth_t t and emu_t *e) */
#ifndef EMU_TABLE_H
#define EMU_TABLE_H

#define EMU_SETTINGS(X)                                                                            \
    X(r_s_ohm, pcfg.r_s_ohm, double)                                                               \
    X(l_d_h, pcfg.l_d_h, double)                                                                   \
    X(l_q_h, pcfg.l_q_h, double)                                                                   \
    X(psi_f_wb, pcfg.psi_f_wb, double)                                                             \
    X(pole_pairs, pcfg.pole_pairs, int)                                                            \
    X(j_kgm2, pcfg.j_kgm2, double)                                                                 \
    X(b_visc_nms, pcfg.b_visc_nms, double)                                                         \
    X(t_coulomb_nm, pcfg.t_coulomb_nm, double)                                                     \
    X(v_dc_v, pcfg.v_dc_v, double)                                                                 \
    X(dead_time_s, pcfg.dead_time_s, double)                                                       \
    X(v_drop_v, pcfg.v_drop_v, double)                                                             \
    X(i_dt_a, pcfg.i_dt_a, double)                                                                 \
    X(i_noise_a, pcfg.i_noise_a, double)                                                           \
    X(adc_lsb_a, pcfg.adc_lsb_a, double)                                                           \
    X(enc_counts, pcfg.enc_counts, uint32_t)                                                       \
    X(enc_offset_m_rad, pcfg.enc_offset_m_rad, double)                                             \
    X(ts_s, pcfg.ts_s, double)                                                                     \
    X(substeps, pcfg.substeps, int)                                                                \
    X(seed, pcfg.seed, uint32_t)                                                                   \
    X(temp_ambient_c, pcfg.temp_ambient_c, double)                                                 \
    X(effects_mask, effects_mask, uint32_t)                                                        \
    X(wiring_swap_bc, wiring_swap_bc, int)                                                         \
    X(wiring_open, wiring_open, int)                                                               \
    X(theta_e0_rad, theta_e0_rad, double)                                                          \
    X(sat_nd, sat_nd, int)                                                                         \
    X(sat_nq, sat_nq, int)                                                                         \
    X(sat_id0_a, sat_id0_a, double)                                                                \
    X(sat_did_a, sat_did_a, double)                                                                \
    X(sat_iq0_a, sat_iq0_a, double)                                                                \
    X(sat_diq_a, sat_diq_a, double)                                                                \
    X(thermal_on, pcfg.thermal_on, int)                                                            \
    X(temp_ref_c, pcfg.temp_ref_c, double)                                                         \
    X(temp_winding0_c, pcfg.temp_winding0_c, double)                                               \
    X(temp_magnet0_c, pcfg.temp_magnet0_c, double)                                                 \
    X(alpha_r_per_k, pcfg.alpha_r_per_k, double)                                                   \
    X(alpha_psi_per_k, pcfg.alpha_psi_per_k, double)                                               \
    X(c_winding_j_k, pcfg.c_winding_j_k, double)                                                   \
    X(c_magnet_j_k, pcfg.c_magnet_j_k, double)                                                     \
    X(r_wa_k_w, pcfg.r_wa_k_w, double)                                                             \
    X(r_wm_k_w, pcfg.r_wm_k_w, double)                                                             \
    X(r_ma_k_w, pcfg.r_ma_k_w, double)                                                             \
    X(r_fe_heat_ohm, pcfg.r_fe_heat_ohm, double)                                                   \
    X(psi5_rel, pcfg.psi5_rel, double)                                                             \
    X(psi7_rel, pcfg.psi7_rel, double)                                                             \
    X(cog_nm, pcfg.cog_nm, double)                                                                 \
    X(cog_order_e, pcfg.cog_order_e, int)                                                          \
    X(cog_phase_rad, pcfg.cog_phase_rad, double)                                                   \
    X(i_a_offset_a, pcfg.i_offset_a[0], double)                                                    \
    X(i_b_offset_a, pcfg.i_offset_a[1], double)                                                    \
    X(i_c_offset_a, pcfg.i_offset_a[2], double)                                                    \
    X(i_a_gain, pcfg.i_gain[0], double)                                                            \
    X(i_b_gain, pcfg.i_gain[1], double)                                                            \
    X(i_c_gain, pcfg.i_gain[2], double)                                                            \
    X(sample_delay_s, pcfg.sample_delay_s, double)                                                 \
    X(pwm_delay_periods, pcfg.pwm_delay_periods, int)                                              \
    X(dc_on, pcfg.dc_on, int)                                                                      \
    X(dc_r_src_ohm, pcfg.dc_r_src_ohm, double)                                                     \
    X(dc_c_f, pcfg.dc_c_f, double)                                                                 \
    X(dc_rectifier, pcfg.dc_rectifier, int)                                                        \
    X(dc_grid_hz, pcfg.dc_grid_hz, double)                                                         \
    X(r_fe_ohm, pcfg.r_fe_ohm, double)                                                             \
    X(baud, baud, double)                                                                          \
    X(can_bitrate, can_bitrate, double)                                                            \
    X(can_node, can_node, uint16_t)                                                                \
    X(truth_hz, truth_hz, double)

#define EMU_TRUTH(X)                                                                               \
    X(t_s, t.t_s)                                                                                  \
    X(i_d_a, t.i_d_a)                                                                              \
    X(i_q_a, t.i_q_a)                                                                              \
    X(theta_e_rad, t.theta_e_rad)                                                                  \
    X(theta_m_rad, t.theta_m_rad)                                                                  \
    X(omega_m_rad_s, t.omega_m_rad_s)                                                              \
    X(speed_rpm, t.speed_rpm)                                                                      \
    X(torque_nm, t.torque_nm)                                                                      \
    X(u_d_v, t.u_d_v)                                                                              \
    X(u_q_v, t.u_q_v)                                                                              \
    X(r_s_ohm, t.r_s_ohm)                                                                          \
    X(l_d_h, t.l_d_h)                                                                              \
    X(l_q_h, t.l_q_h)                                                                              \
    X(psi_f_wb, t.psi_f_wb)                                                                        \
    X(temp_winding_c, t.temp_winding_c)                                                            \
    X(temp_magnet_c, t.temp_magnet_c)                                                              \
    X(i_a_a, t.i_a_a)                                                                              \
    X(i_b_a, t.i_b_a)                                                                              \
    X(i_c_a, t.i_c_a)                                                                              \
    X(v_dc_v, t.v_dc_v)                                                                            \
    X(load_nm, t.load_nm)                                                                          \
    X(psi_d_wb, t.psi_d_wb)                                                                        \
    X(psi_q_wb, t.psi_q_wb)                                                                        \
    X(p_cu_w, t.p_cu_w)                                                                            \
    X(p_fe_w, t.p_fe_w)                                                                            \
    X(i_dc_a, t.i_dc_a)                                                                            \
    X(tick, (double)fw_tick(&e->fw))                                                               \
    X(v_dist_a_v, t.v_dist_v[0])                                                                   \
    X(v_dist_b_v, t.v_dist_v[1])                                                                   \
    X(v_dist_c_v, t.v_dist_v[2])

#endif
