/* The emulator's plant: an interior-permanent-magnet synchronous motor (IPMSM) fed by a two-level
 * voltage-source inverter, with its sensors (phase-current ADC, DC-link voltage, incremental
 * encoder) and a load machine. Double precision, deterministic, about 100 ns per control period.
 *
 * The sim board calls, every control period Ts:
 *     plant_sample(&p, &meas);        measurement at the period boundary (ADC sample instant)
 *     cmd = firmware_isr(&meas);
 *     plant_step(&p, &cmd_prev);      advance one period with the previous command held
 *
 * Model (docs/plant.md has the derivation, the integration error and the effect seams):
 *   u_d = R i_d + dpsi_d/dt - w_e psi_q,  u_q = R i_q + dpsi_q/dt + w_e psi_d,
 *   linear magnetics psi_d = L_d i_d + psi_f, psi_q = L_q i_q (plant_flux() is the one place that
 *   maps currents to flux linkages and incremental inductances),
 *   T_e = 1.5 p (psi_d i_q - psi_q i_d),  J dw_m/dt = T_e - T_load - b w_m - T_c sgn(w_m)
 *   with a sticking (Karnopp) Coulomb friction,
 *   inverter: switch states -> phase voltages (constant in the stationary frame over the period,
 *   rotated into dq as the rotor turns), minus a smooth dead-time / device-drop distortion voltage;
 *   PWM off: diode bridge with current-zero blocking,
 *   RK4 with `substeps` sub-steps per period.
 * Units are SI; angles in rad; electrical angle theta_e = p * theta_m, d axis on phase a at 0.
 */
#ifndef PLANT_H
#define PLANT_H

#include <stdint.h>
#include <stdbool.h>

#include "fw_types.h"
#include "rng.h"

typedef struct {
    /* motor */
    double r_s_ohm;          /* stator resistance per phase */
    double l_d_h;            /* d-axis inductance */
    double l_q_h;            /* q-axis inductance */
    double psi_f_wb;         /* permanent-magnet flux linkage (amplitude) */
    int pole_pairs;
    double j_kgm2;           /* rotor + load inertia */
    double b_visc_nms;       /* viscous friction, N*m per rad/s */
    double t_coulomb_nm;     /* Coulomb (dry) friction, sticking at standstill */
    /* inverter */
    double v_dc_v;           /* DC-link voltage */
    double dead_time_s;      /* 0 disables the dead-time term */
    double v_drop_v;         /* switch / diode forward drop, 0 disables */
    double i_dt_a;           /* current scale of the smooth sign sigma(i / i_dt_a); <= 0 disables both terms */
    /* sensors */
    double i_noise_a;        /* standard deviation of the Gaussian current-sensor noise, 0 = off */
    double adc_lsb_a;        /* current quantisation step, 0 = off */
    uint32_t enc_counts;     /* encoder counts per mechanical revolution (lines * 4) */
    double enc_offset_rad;   /* encoder reads wrap(theta_m + enc_offset_rad) */
    /* integration */
    double ts_s;             /* control period */
    int substeps;            /* RK4 sub-steps per period (1: within ~3e-5 A of a 1000-step reference, docs/plant.md) */
    uint32_t seed;           /* noise seed */
    /* additions */
    double temp_ambient_c;   /* initial winding and magnet temperature (reported in the truth) */
} plant_cfg_t;

/* Flux linkages and incremental inductances at one operating point: what plant_flux() returns. */
typedef struct {
    double psi_d_wb, psi_q_wb;           /* flux linkages */
    double g_dd, g_dq, g_qd, g_qq;       /* inverse of the incremental inductance matrix d(psi)/d(i), 1/H */
    double dpsi_d_dth_wb, dpsi_q_dth_wb; /* d(psi)/d(theta_e) at constant current (flux harmonics), Wb/rad */
    double t_extra_nm;                   /* torque not given by psi x i (cogging = d(co-energy)/d(theta_m)) */
} plant_mag_t;

typedef struct {
    plant_cfg_t cfg;
    /* state */
    double i_d_a, i_q_a;        /* stator currents, rotor frame */
    double theta_m_rad;         /* mechanical angle, wrapped to [0, 2 pi) */
    double omega_m_rad_s;       /* mechanical speed */
    double cos_e, sin_e;        /* cos, sin of the electrical angle pole_pairs * theta_m */
    double v_dc_v;              /* DC-link voltage in force (a state, so that DC-link dynamics can come) */
    double temp_winding_c, temp_magnet_c;
    /* parameters in force (nominal now; temperature and saturation effects will move them) */
    double r_s_ohm, l_d_h, l_q_h, psi_f_wb;
    /* inverter memory */
    uint16_t s_prev[3];         /* switch states of the last period (for the dead-time transitions) */
    bool pwm_prev;              /* PWM was on in the last period */
    int8_t diode[3];            /* PWM off: +1 lower diode conducts (i > 0), -1 upper (i < 0), 0 blocked */
    bool diodes_valid;          /* diode[] belongs to the current state (the last period was PWM off) */
    bool hold_speed;            /* speed imposed (ideal dyno / test): omega_m does not change */
    bool dist_on;               /* inverter distortion (dead time or device drop) configured */
    double load_nm;             /* load torque in force */
    /* last period, for the truth */
    double u_d_avg_v, u_q_avg_v;    /* applied dq voltage averaged over the last period */
    uint64_t n_periods;
    /* derived constants (plant_init) */
    double inv_l_d, inv_l_q, inv_j, inv_i_dt, inv_lsb, enc_scale, enc_off_w, h_s, inv_ts;
    rng_t rng;
} plant_t;

typedef struct {
    double i_d_a, i_q_a, theta_e_rad, theta_m_rad, omega_m_rad_s, speed_rpm, torque_nm, u_d_v, u_q_v;
    double r_s_ohm, l_d_h, l_q_h, psi_f_wb, temp_winding_c, temp_magnet_c;
    /* additions */
    double t_s;                         /* time since plant_init: n_periods * ts_s */
    double i_a_a, i_b_a, i_c_a;         /* true phase currents */
    double omega_e_rad_s, v_dc_v, load_nm;
} plant_truth_t;

/* Paper A's IPMSM (p 4, R 0.9, Ld 5 mH, Lq 12 mH, psi_f 0.18 Wb, J 0.0036) on 540 V, Ts 50 us,
 * ideal inverter and sensors, 2500-line encoder, 1 substep, seed 1, 25 degC. */
void plant_cfg_default(plant_cfg_t *cfg);
/* NULL when cfg is usable, else a static message naming the first bad field. */
const char *plant_cfg_check(const plant_cfg_t *cfg);

void plant_init(plant_t *p, const plant_cfg_t *cfg);        /* standstill, i = 0, theta_m = 0 */
void plant_sample(plant_t *p, fw_meas_t *m);                 /* sensors at the current instant */
void plant_step(plant_t *p, const fw_cmd_t *cmd);            /* one period, switch states held */
void plant_truth(const plant_t *p, plant_truth_t *t);

/* Averaged PWM: one period with leg duties d in [0, 1] (each leg with 0 < d < 1 commutes twice,
 * so the dead-time error is the classic -v_dc t_d / Ts * sigma(i)). */
void plant_step_duty(plant_t *p, const double duty[3], bool pwm_on, double load_nm);
/* Ideal voltage source in the rotor frame (no inverter): one period with (u_d, u_q) held. */
void plant_step_udq(plant_t *p, double u_d_v, double u_q_v, double load_nm);

/* Put the rotor at theta_m with speed omega_m; hold_speed freezes the speed (ideal speed-controlled dyno). */
void plant_set_mech(plant_t *p, double theta_m_rad, double omega_m_rad_s, bool hold_speed);
/* Set the stator currents (rotor frame), e.g. to start a test at an operating point. */
void plant_set_currents(plant_t *p, double i_d_a, double i_q_a);

/* The magnetics seam: flux linkages, inverse incremental inductances, angle derivatives, extra torque. */
void plant_flux(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad, plant_mag_t *m);
/* Electromagnetic torque at the given currents and electrical angle. */
double plant_torque(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad);
/* Smooth sign used by the inverter distortion: x (27 + x^2) / (27 + 9 x^2) for |x| < 3, sgn x beyond
 * (C1, monotonic, within 0.025 of tanh). */
double plant_sigmoid(double x);
/* Average distortion voltage of one leg over one period, added to its terminal voltage:
 * -v_drop sigma(i/i_dt) (conducting device) plus the dead-time volt-seconds v_dc t_d / Ts of the leg's
 * commutations in the period, weighted by sigma: transition +1 = rising edge (0 -> 1) at the period
 * start, -1 = falling edge, 0 = none, 2 = one rising and one falling edge (carrier PWM), which gives
 * the classic -(v_dc t_d / Ts) sigma(i). */
double plant_leg_distortion_v(const plant_t *p, double i_a, int transition);

#endif
