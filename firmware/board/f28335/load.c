/* Load-machine hook: the load torque the profile asks for (fw_cmd_t.load_nm) as an analogue
 * command to the load machine's drive, through a PWM-DAC on ePWM4A (GPIO6): 100 kHz up count,
 * set at zero, clear at CMPA; duty 50 % = 0 N m, 0 % / 100 % = -/+ BOARD_LOAD_FULLSCALE_NM.
 * A second-order RC filter (corner ~1 kHz) and a level shifter to the drive's +-10 V torque input
 * follow on the rig. The core sends 0 N m whenever the PWM is off or the run stops.
 * To command the load over CAN instead (the load drive's own protocol), replace
 * load_set_torque(); it is called once per control period from the control ISR, so it must not
 * block (queue the frame, let a mailbox interrupt send it). */
#include "board.h"
#include "board_calc.h"

#define LOAD_TBPRD ((uint16_t)(BOARD_SYSCLK_HZ / BOARD_LOAD_PWM_HZ - 1UL))

void load_init(void)
{
    EALLOW;
    GpioCtrlRegs.GPAPUD.bit.GPIO6 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO6 = 1u; /* EPWM4A */
    EDIS;

    EPwm4Regs.TBCTL.all = 0u;
    EPwm4Regs.TBCTL.bit.CTRMODE = TB_FREEZE;
    EPwm4Regs.TBCTL.bit.PRDLD = TB_SHADOW;
    EPwm4Regs.TBCTL.bit.PHSEN = TB_DISABLE;
    EPwm4Regs.TBCTL.bit.SYNCOSEL = TB_SYNC_DISABLE;
    EPwm4Regs.TBCTL.bit.HSPCLKDIV = TB_DIV1;
    EPwm4Regs.TBCTL.bit.CLKDIV = TB_DIV1;
    EPwm4Regs.TBCTL.bit.FREE_SOFT = 2u;
    EPwm4Regs.TBPRD = LOAD_TBPRD;
    EPwm4Regs.TBCTR = 0u;
    EPwm4Regs.CMPCTL.all = 0u; /* CMPA shadowed, loaded at CTR = 0 */
    EPwm4Regs.CMPA.half.CMPA = calc_dac_cmpa(0.0f, BOARD_LOAD_FULLSCALE_NM, LOAD_TBPRD);
    EPwm4Regs.AQCTLA.all = 0u;
    EPwm4Regs.AQCTLA.bit.ZRO = AQ_SET;
    EPwm4Regs.AQCTLA.bit.CAU = AQ_CLEAR;
    EPwm4Regs.AQCTLB.all = 0u;
    EPwm4Regs.DBCTL.all = 0u;
    EPwm4Regs.ETSEL.all = 0u;
    EPwm4Regs.TBCTL.bit.CTRMODE = TB_COUNT_UP; /* runs once TBCLKSYNC is set (pwm_start) */
}

BOARD_RAMFUNC void load_set_torque(float load_nm)
{
    EPwm4Regs.CMPA.half.CMPA = calc_dac_cmpa(load_nm, BOARD_LOAD_FULLSCALE_NM, LOAD_TBPRD);
}
