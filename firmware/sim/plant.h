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

/* Flux map for saturation and cross-saturation: psi_d(i_d, i_q), psi_q(i_d, i_q) on a regular grid,
 * interpolated by bicubic Hermite patches (C1: the incremental inductances are continuous), extended
 * linearly beyond the grid with the boundary's incremental inductances. Built by plant_map_build(). */
#define PLANT_MAP_MAX_N 64
typedef struct {
    int nd, nq;          /* nodes along i_d and i_q, 2 .. PLANT_MAP_MAX_N */
    double id0_a, iq0_a; /* first node */
    double did_a, diq_a; /* node spacing */
    double inv_did, inv_diq;
    double psi_f_wb; /* psi_d(0, 0) of the map: its magnet flux linkage */
    double coef[(PLANT_MAP_MAX_N - 1) * (PLANT_MAP_MAX_N - 1)][16]
               [2]; /* per cell: coefficient of t^a v^b (index a*4+b) for psi_d, psi_q */
} plant_map_t;

typedef struct {
    /* motor */
    double r_s_ohm;  /* stator resistance per phase */
    double l_d_h;    /* d-axis inductance */
    double l_q_h;    /* q-axis inductance */
    double psi_f_wb; /* permanent-magnet flux linkage (amplitude) */
    int pole_pairs;
    double j_kgm2;       /* rotor + load inertia */
    double b_visc_nms;   /* viscous friction, N*m per rad/s */
    double t_coulomb_nm; /* Coulomb (dry) friction, sticking at standstill */
    /* inverter */
    double v_dc_v;      /* DC-link voltage */
    double dead_time_s; /* 0 disables the dead-time term */
    double v_drop_v;    /* switch / diode forward drop, 0 disables */
    double
        i_dt_a; /* current scale of the smooth sign sigma(i / i_dt_a); <= 0 disables both terms */
    /* sensors */
    double i_noise_a;        /* standard deviation of the Gaussian current-sensor noise, 0 = off */
    double adc_lsb_a;        /* current quantisation step, 0 = off */
    uint32_t enc_counts;     /* encoder counts per mechanical revolution (lines * 4) */
    double enc_offset_m_rad; /* encoder reads wrap(theta_m + enc_offset_m_rad) */
    /* integration */
    double ts_s; /* control period */
    int substeps; /* RK4 sub-steps per period (1: within ~3e-5 A of a 1000-step reference, docs/plant.md) */
    uint32_t seed; /* noise seed */
    /* additions */
    double
        temp_ambient_c; /* ambient; also the initial winding and magnet temperature unless thermal_on */
    /* ---- rig effects (docs/rigs.md); every one is off at its default (plant_cfg_default) */
    const plant_map_t *map; /* saturation: flux map (NULL: linear L_d, L_q, psi_f) */
    int thermal_on;    /* thermal network: R and psi_f follow the winding and magnet temperatures */
    double temp_ref_c; /* temperature at which r_s_ohm and psi_f_wb (or the map) hold */
    double temp_winding0_c, temp_magnet0_c; /* initial temperatures */
    double alpha_r_per_k;   /* R = R_ref (1 + alpha_r (T_w - T_ref)); copper 0.00393 */
    double alpha_psi_per_k; /* psi_f = psi_f_ref (1 + alpha_psi (T_m - T_ref)); NdFeB -0.001 */
    double c_winding_j_k, c_magnet_j_k; /* heat capacities */
    double r_wa_k_w, r_wm_k_w,
        r_ma_k_w;         /* thermal resistances winding-ambient, winding-magnet, magnet-ambient */
    double r_fe_heat_ohm; /* iron loss heating when r_fe_ohm is 0 (P = 1.5 |e|^2 / R); 0: none */
    double psi5_rel,
        psi7_rel;         /* flux harmonics: 5th (rotating backwards) and 7th, relative to psi_f */
    double cog_nm;        /* cogging torque amplitude, 0 = off */
    int cog_order_e;      /* cogging periods per electrical revolution (= per mechanical rev / p) */
    double cog_phase_rad; /* T_cog = cog_nm sin(cog_order_e theta_e + cog_phase_rad) */
    double i_offset_a[3]; /* current-sensor offsets a, b, c */
    double i_gain[3];     /* current-sensor gains a, b, c (1 = exact) */
    double
        sample_delay_s; /* current sample taken this long before the period boundary (linear interpolation) */
    int pwm_delay_periods; /* command applied this many periods later than the board's one-period delay */
    int dc_on;             /* DC link: source resistance, capacitor, rectifier ripple */
    double dc_r_src_ohm; /* source (grid + rectifier) resistance */
    double dc_c_f;       /* DC-link capacitance */
    int dc_rectifier; /* 1: six-pulse diode rectifier from a grid whose line peak is v_dc_v; 0: DC source v_dc_v */
    double dc_grid_hz;
    double r_fe_ohm; /* iron loss: equivalent resistance across the speed voltage, 0 = off */
} plant_cfg_t;

#define PLANT_THERMAL_DIV 16 /* the thermal network steps every 16 periods */
/* sample_delay_s < (PLANT_DELAY_RING - 2) ts_s; pwm_delay_periods < PLANT_DELAY_RING */
#define PLANT_DELAY_RING 32

/* Flux linkages and incremental inductances at one operating point: what plant_flux() returns. */
typedef struct {
    double psi_d_wb, psi_q_wb; /* flux linkages */
    double g_dd, g_dq, g_qd,
        g_qq; /* inverse of the incremental inductance matrix d(psi)/d(i), 1/H */
    double dpsi_d_dth_wb,
        dpsi_q_dth_wb; /* d(psi)/d(theta_e) at constant current (flux harmonics), Wb/rad */
    double t_extra_nm; /* torque not given by psi x i (cogging = d(co-energy)/d(theta_m)) */
    double l_dd, l_dq, l_qd, l_qq; /* incremental inductance matrix d(psi)/d(i), H */
} plant_mag_t;

typedef struct {
    plant_cfg_t cfg;
    /* state */
    double i_d_a, i_q_a;  /* stator currents, rotor frame */
    double theta_m_rad;   /* mechanical angle, wrapped to [0, 2 pi) */
    double omega_m_rad_s; /* mechanical speed */
    double cos_e, sin_e;  /* cos, sin of the electrical angle pole_pairs * theta_m */
    double v_dc_v; /* DC-link voltage in force (a state, so that DC-link dynamics can come) */
    double temp_winding_c, temp_magnet_c;
    /* parameters in force (nominal now; temperature and saturation effects will move them) */
    double r_s_ohm, l_d_h, l_q_h, psi_f_wb;
    /* inverter memory */
    uint16_t s_prev[3]; /* switch states of the last period (for the dead-time transitions) */
    bool pwm_prev;      /* PWM was on in the last period */
    int8_t diode[3];    /* PWM off: +1 lower diode conducts (i > 0), -1 upper (i < 0), 0 blocked */
    bool diodes_valid;  /* diode[] belongs to the current state (the last period was PWM off) */
    bool hold_speed;    /* speed imposed (ideal dyno / test): omega_m does not change */
    bool dist_on;       /* inverter distortion (dead time or device drop) configured */
    double load_nm;     /* load torque in force */
    /* last period, for the truth */
    double u_d_avg_v, u_q_avg_v; /* applied dq voltage averaged over the last period */
    uint64_t n_periods;
    /* derived constants (plant_init) */
    double inv_l_d, inv_l_q, inv_j, inv_i_dt, inv_lsb, enc_scale, enc_off_w, h_s, inv_ts;
    rng_t rng;
    /* rig effects: state and derived constants */
    bool mag_general;  /* saturation, flux harmonics, cogging or iron loss: general magnetics */
    bool sens_general; /* sensor offset/gain or sample delay */
    double
        psi_f_ref_wb; /* magnet flux linkage at temp_ref (the map's psi_d(0,0) with saturation) */
    double psi_shift_wb;   /* psi_f in force - psi_f_ref (added to the map's psi_d) */
    double inv_r_fe;       /* 1 / r_fe_ohm, 0 = no iron loss */
    double p_cu_w, p_fe_w; /* thermal: losses of the last thermal step */
    double th_acc_w;       /* thermal: copper loss summed over the periods of this step */
    int th_n;              /* thermal: periods in this step so far */
    double cog_c, cog_s;   /* cos, sin of cog_phase_rad */
    double hist_i[PLANT_DELAY_RING][3]; /* true phase currents at the last period boundaries */
    uint32_t hist_pos;
    int delay_n;                        /* whole periods of sample delay */
    double delay_f;                     /* fraction of a period beyond delay_n */
    double fifo_d[PLANT_DELAY_RING][3]; /* PWM delay: commands waiting */
    bool fifo_on[PLANT_DELAY_RING];
    bool fifo_carrier[PLANT_DELAY_RING];
    uint32_t fifo_pos;
    double grid_c, grid_s, grid_dc, grid_ds; /* DC link: grid phasor and its rotation per period */
    double v_src_v;                          /* DC link: no-load DC voltage (cfg v_dc_v) */
    double i_dc_a;      /* DC link: inverter input current of the last period */
    double v_dist_v[3]; /* inverter distortion voltage of each leg in the last period (truth) */
    /* apparent L_d with a flux map (plant_truth): 1 ms means of i_d and psi_d, and exponentially
     * weighted sums of the least-squares line psi_d = psi_f,app + L_d,app i_d through them; the
     * sums of i_q and psi_q for the apparent L_q (their ratio) */
    int app_n;
    double app_blk_i, app_blk_psi, app_blk_iq, app_blk_psiq;
    double app_s0, app_si, app_sp, app_sii, app_sip, app_sq, app_spq;
    /* the flux map at the end-of-period currents, evaluated for the apparent L_d: the next
     * period's first RK4 stage asks for it again (mag_gen takes it from here) */
    int map_memo_ok;
    double map_memo_id, map_memo_iq, map_memo_pd, map_memo_pq, map_memo_l[4];
} plant_t;

typedef struct {
    double i_d_a, i_q_a, theta_e_rad, theta_m_rad, omega_m_rad_s, speed_rpm, torque_nm, u_d_v,
        u_q_v;
    double r_s_ohm, l_d_h, l_q_h, psi_f_wb, temp_winding_c, temp_magnet_c;
    /* additions */
    double t_s;                 /* time since plant_init: n_periods * ts_s */
    double i_a_a, i_b_a, i_c_a; /* true phase currents */
    double omega_e_rad_s, v_dc_v, load_nm;
    /* rig effects */
    double psi_d_wb, psi_q_wb; /* flux linkages in force */
    double l_dq_h;             /* incremental cross inductance d(psi_d)/d(i_q) */
    /* apparent (secant) inductances at the operating point, what steady-state equations identify
     * (docs/identification.md): psi_q / i_q, and (psi_d - psi_d(0, i_q)) / i_d; the incremental
     * ones below 0.05 A, their limits */
    double l_d_secant_h, l_q_secant_h;
    double p_cu_w, p_fe_w; /* copper and iron losses */
    double i_dc_a;         /* DC-link current into the inverter (last period, DC link on) */
    double v_dist_v[3];    /* inverter distortion (dead time, drops) of legs a, b, c, last period */
} plant_truth_t;

/* Paper A's IPMSM (p 4, R 0.9, Ld 5 mH, Lq 12 mH, psi_f 0.18 Wb, J 0.0036) on 540 V, Ts 50 us,
 * ideal inverter and sensors, 2500-line encoder, 1 substep, seed 1, 25 degC. */
void plant_cfg_default(plant_cfg_t *cfg);
/* NULL when cfg is usable, else a static message naming the first bad field. */
const char *plant_cfg_check(const plant_cfg_t *cfg);

void plant_init(plant_t *p, const plant_cfg_t *cfg); /* standstill, i = 0, theta_m = 0 */
void plant_sample(plant_t *p, fw_meas_t *m);         /* sensors at the current instant */
void plant_step(plant_t *p,
                const fw_cmd_t *cmd); /* one period: switch states held, or duties (cmd->mode) */
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
/* Build a flux map from node values (node (j, k) = (id0 + j did, iq0 + k diq) at index k * nd + j);
 * node derivatives by finite differences. NULL, or a message naming the bad argument. */
const char *plant_map_build(plant_map_t *m, int nd, int nq, double id0_a, double did_a,
                            double iq0_a, double diq_a, const double *psi_d_wb,
                            const double *psi_q_wb);
/* The map alone at one point: psi_d, psi_q and the incremental inductances l[4] = dd, dq, qd, qq. */
void plant_map_eval(const plant_map_t *m, double i_d_a, double i_q_a, double *psi_d_wb,
                    double *psi_q_wb, double l[4]);

/* Smooth sign used by the inverter distortion: x (27 + x^2) / (27 + 9 x^2) for |x| < 3, sgn x beyond
 * (C1, monotonic, within 0.025 of tanh). */
double plant_sigmoid(double x);
/* Average distortion voltage of one leg over one period, added to its terminal voltage:
 * -v_drop sigma(i/i_dt) (conducting device) plus the dead-time volt-seconds v_dc t_d / Ts of the leg's
 * commutations in the period, weighted by sigma: transition +1 = rising edge (0 -> 1) at the period
 * start, -1 = falling edge, 0 = none, 2 = one rising and one falling edge (carrier PWM), which gives
 * the classic -(v_dc t_d / Ts) sigma(i). */
double plant_leg_distortion_v(const plant_t *p, double i_a, int transition);

/* Drift tests (issue 3): step the plant's true R and psi_f to base x scale, where base is the cfg the
 * plant was initialised with (the sim board's). The thermal model, when on, keeps applying its
 * temperature factor on top. (With a flux map the psi_f step enters as a shift of psi_d.) */
void plant_set_param_scale(plant_t *p, const plant_cfg_t *base, double r_s_scale,
                           double psi_f_scale);

#endif
