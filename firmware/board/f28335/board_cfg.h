/* Board constants of the F28335 board support (docs/board-f28335.md): clocks, control timing,
 * pin-out choices, sensor calibration, link speed. Adapting the firmware to another power stage
 * or sensor scaling means editing this file only.
 * Integer constants above 16 bits carry UL: int is 16-bit on the C28x. */
#ifndef BOARD_CFG_H
#define BOARD_CFG_H

/* ------------------------------------------------------------------ clocks */
#define BOARD_OSCCLK_HZ  30000000UL /* crystal/oscillator on X1/X2 (XCLKIN): 30 MHz */
#define BOARD_PLLCR_DIV  10u        /* PLLCR.DIV (0..10 on the F2833x): x10 = 300 MHz */
#define BOARD_PLL_DIVSEL 2u         /* PLLSTS.DIVSEL: /2 -> SYSCLKOUT 150 MHz */
#define BOARD_SYSCLK_HZ  150000000UL
#define BOARD_SYSCLK_MHZ 150UL
#define BOARD_HISPCP     3u /* HSPCLK = SYSCLKOUT / (2 x 3) = 25 MHz (ADC) */
#define BOARD_LOSPCP     2u /* LSPCLK = SYSCLKOUT / (2 x 2) = 37.5 MHz (SCI) */
#define BOARD_LSPCLK_HZ  37500000UL

#if (BOARD_OSCCLK_HZ * BOARD_PLLCR_DIV / 2UL) != BOARD_SYSCLK_HZ
#error "board_cfg.h: OSCCLK x PLLCR / 2 must give BOARD_SYSCLK_HZ"
#endif
#if (BOARD_SYSCLK_HZ / (2UL * BOARD_LOSPCP)) != BOARD_LSPCLK_HZ
#error "board_cfg.h: LOSPCP does not give BOARD_LSPCLK_HZ"
#endif

/* ------------------------------------------------------------------ control period, PWM */
/* Until the host's config_ctrl sets ts_s (accepted range 10 us .. 1 ms), the ePWMs run at this. */
#define BOARD_TS_DEFAULT_S 50.0e-6f
/* Hardware dead time inserted by the ePWM dead-band unit on every edge (2 us = 300 TBCLK at
 * 150 MHz). The power stage's datasheet sets the minimum; config_ctrl.dead_time_s (the MPCC's
 * compensation) should be set to the same value in the rig file. */
#define BOARD_DEAD_TIME_NS 2000UL
/* The ADC start of conversion comes this long before the period start (CTR = 0, where the new
 * switch state is loaded and the legs switch), so that the sample-and-hold windows close before
 * the switching edge and its ringing. 0: SOC exactly at CTR = 0. Must stay below the shortest
 * control ISR (it does: an active period costs >= 10 us), see docs/board-f28335.md. */
#define BOARD_ADC_LEAD_NS 1000UL

/* Gate-driver enable output (active high, pulled low on the power stage): 1 = fitted. */
#define BOARD_HAVE_GATE_EN 1
/* Hardware over-current trip on TZ1 (GPIO12, active low) as a one-shot trip of all legs. */
#define BOARD_USE_TZ1 1

/* ------------------------------------------------------------------ ADC */
/* Simultaneous-sampling pairs (ADCINAn and ADCINBn sampled at the same instant). */
#define BOARD_ADC_PAIR_IAB 1u /* ADCINA1 = i_a, ADCINB1 = i_b */
#define BOARD_ADC_PAIR_ICV 2u /* ADCINA2 = i_c, ADCINB2 = v_dc */
#define BOARD_HAVE_IC      1  /* third phase-current sensor fitted; 0: i_c = -(i_a + i_b) */
#define BOARD_ADC_ACQ_PS   2u /* S/H window (ACQ_PS + 1) ADCCLK = 240 ns at 12.5 MHz */

/* Calibration: value_SI = (raw - offset) x gain, raw = 12-bit result 0..4095 over 0..3 V.
 * Phase currents: in-line sensors centred at 1.5 V, +-30 A full scale (60 A / 4096 LSB).
 * Gains are signed: positive current flows from the inverter into the motor terminal. */
#define BOARD_IA_GAIN_A_PER_LSB    0.0146484375f
#define BOARD_IB_GAIN_A_PER_LSB    0.0146484375f
#define BOARD_IC_GAIN_A_PER_LSB    0.0146484375f
#define BOARD_I_OFFSET_NOMINAL_LSB 2048.0f /* 1.5 V at 0 A */
#define BOARD_I_OFFSET_TOL_LSB     120.0f  /* boot calibration accepted within +-this (+-88 mV) */
#define BOARD_ADC_CAL_SAMPLES      1024u   /* boot offset calibration: 51 ms at 20 kHz, PWM off */
#define BOARD_ADC_CAL_TIMEOUT_US   500000UL
/* DC link: divider + isolation amplifier, 0..750 V over 0..3 V (750 V / 4096 LSB). */
#define BOARD_VDC_GAIN_V_PER_LSB 0.18310546875f
#define BOARD_VDC_OFFSET_LSB     0.0f

/* A board fault (hardware trip, implausible current-sensor offsets) is reported to the core as
 * this phase current, which trips its over-current check (the core has no board-fault input). */
#define BOARD_FAULT_REPORT_A 1.0e6f

/* ------------------------------------------------------------------ encoder (eQEP1) */
#define BOARD_ENC_COUNTS_DEFAULT 10000UL /* 2500 lines x 4; config_ctrl.enc_counts replaces it */
#define BOARD_QEP_SWAP           0u      /* 1: swap A/B (reverse the counting direction) */
#define BOARD_QEP_USE_INDEX      1       /* index pulse defines count 0 (taken only between runs) */

/* ------------------------------------------------------------------ SCI-A link */
/* 921600 or 460800; with LSPCLK = 37.5 MHz both come out 1.73 % fast (docs/board-f28335.md). */
#define BOARD_SCI_BAUD          921600UL
#define BOARD_SCI_FIFO_DEPTH    16u
#define BOARD_SCI_TX_FIFO_LEVEL 8u /* TX FIFO interrupt when <= this many octets remain */

/* ------------------------------------------------------------------ load machine hook */
/* Torque command to the load machine's drive as a PWM-DAC on ePWM4A (GPIO6): duty 50 % = 0 N m,
 * 0 % / 100 % = -/+ full scale, behind an RC filter and an amplifier to the drive's analogue
 * torque input (e.g. +-10 V). */
#define BOARD_LOAD_PWM_HZ       100000UL
#define BOARD_LOAD_FULLSCALE_NM 10.0f

/* ------------------------------------------------------------------ CAN */
#define BOARD_CAN_NODE 0u /* fw_cfg_t.can_node (docs/can.md); eCAN not wired yet */

#endif
