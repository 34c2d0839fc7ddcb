/* HOST-ONLY STUB. This file exists only to compile-check the F28335 board code on a PC
 * (make -C firmware/board/f28335 hostcheck: gcc -fsyntax-only). It is NOT TI's header and is
 * never used by the real build, which includes DSP2833x_Device.h from C2000Ware
 * (device_support/f2833x/headers/include). It declares only the registers and fields the board
 * code uses, with the names and bit widths of TI's headers (V1.32); field order and reserved
 * padding are kept where the board code relies on them (consecutive PIEIER/PIEIFR registers).
 * Nothing here models hardware behaviour. */
#ifndef DSP2833x_DEVICE_H
#define DSP2833x_DEVICE_H

#include <stdint.h>

typedef int16_t int16;
typedef int32_t int32;
typedef uint16_t Uint16;
typedef uint32_t Uint32;
typedef float float32;

/* C28x keywords and intrinsics */
#define __interrupt
#define cregister
extern volatile Uint16 IFR;
extern volatile Uint16 IER;
#define EINT ((void)0)
#define DINT ((void)0)
#define ERTM ((void)0)
#define DRTM ((void)0)
#define EALLOW ((void)0)
#define EDIS ((void)0)
#define ESTOP0 ((void)0)

#define M_INT1 0x0001
#define M_INT9 0x0100
#define PIEACK_GROUP1 0x0001
#define PIEACK_GROUP9 0x0100

/* ------------------------------------------------------------------ system control, flash */
struct PLLSTS_BITS { Uint16 PLLLOCKS:1; Uint16 rsvd1:1; Uint16 PLLOFF:1; Uint16 MCLKSTS:1;
                     Uint16 MCLKCLR:1; Uint16 OSCOFF:1; Uint16 MCLKOFF:1; Uint16 DIVSEL:2; Uint16 rsvd2:7; };
union PLLSTS_REG { Uint16 all; struct PLLSTS_BITS bit; };
union HISPCP_REG { Uint16 all; };
union LOSPCP_REG { Uint16 all; };
struct PCLKCR0_BITS { Uint16 rsvd1:2; Uint16 TBCLKSYNC:1; Uint16 ADCENCLK:1; Uint16 I2CAENCLK:1;
                      Uint16 SCICENCLK:1; Uint16 rsvd2:2; Uint16 SPIAENCLK:1; Uint16 rsvd3:1;
                      Uint16 SCIAENCLK:1; Uint16 SCIBENCLK:1; Uint16 MCBSPAENCLK:1; Uint16 MCBSPBENCLK:1;
                      Uint16 ECANAENCLK:1; Uint16 ECANBENCLK:1; };
union PCLKCR0_REG { Uint16 all; struct PCLKCR0_BITS bit; };
struct PCLKCR1_BITS { Uint16 EPWM1ENCLK:1; Uint16 EPWM2ENCLK:1; Uint16 EPWM3ENCLK:1; Uint16 EPWM4ENCLK:1;
                      Uint16 EPWM5ENCLK:1; Uint16 EPWM6ENCLK:1; Uint16 rsvd1:2; Uint16 ECAP1ENCLK:1;
                      Uint16 ECAP2ENCLK:1; Uint16 ECAP3ENCLK:1; Uint16 ECAP4ENCLK:1; Uint16 ECAP5ENCLK:1;
                      Uint16 ECAP6ENCLK:1; Uint16 EQEP1ENCLK:1; Uint16 EQEP2ENCLK:1; };
union PCLKCR1_REG { Uint16 all; struct PCLKCR1_BITS bit; };
struct PCLKCR3_BITS { Uint16 rsvd1:8; Uint16 CPUTIMER0ENCLK:1; Uint16 CPUTIMER1ENCLK:1;
                      Uint16 CPUTIMER2ENCLK:1; Uint16 DMAENCLK:1; Uint16 XINTFENCLK:1;
                      Uint16 GPIOINENCLK:1; Uint16 rsvd2:2; };
union PCLKCR3_REG { Uint16 all; struct PCLKCR3_BITS bit; };
struct PLLCR_BITS { Uint16 DIV:4; Uint16 rsvd1:12; };
union PLLCR_REG { Uint16 all; struct PLLCR_BITS bit; };
struct SYS_CTRL_REGS {
    union PLLSTS_REG PLLSTS;
    union HISPCP_REG HISPCP;
    union LOSPCP_REG LOSPCP;
    union PCLKCR0_REG PCLKCR0;
    union PCLKCR1_REG PCLKCR1;
    union PCLKCR3_REG PCLKCR3;
    union PLLCR_REG PLLCR;
    Uint16 SCSR;
    Uint16 WDCNTR;
    Uint16 WDKEY;
    Uint16 WDCR;
};
extern volatile struct SYS_CTRL_REGS SysCtrlRegs;

struct FOPT_BITS { Uint16 ENPIPE:1; Uint16 rsvd:15; };
union FOPT_REG { Uint16 all; struct FOPT_BITS bit; };
struct FSTDBYWAIT_BITS { Uint16 STDBYWAIT:9; Uint16 rsvd:7; };
union FSTDBYWAIT_REG { Uint16 all; struct FSTDBYWAIT_BITS bit; };
struct FACTIVEWAIT_BITS { Uint16 ACTIVEWAIT:9; Uint16 rsvd:7; };
union FACTIVEWAIT_REG { Uint16 all; struct FACTIVEWAIT_BITS bit; };
struct FBANKWAIT_BITS { Uint16 RANDWAIT:4; Uint16 rsvd1:4; Uint16 PAGEWAIT:4; Uint16 rsvd2:4; };
union FBANKWAIT_REG { Uint16 all; struct FBANKWAIT_BITS bit; };
struct FOTPWAIT_BITS { Uint16 OTPWAIT:5; Uint16 rsvd:11; };
union FOTPWAIT_REG { Uint16 all; struct FOTPWAIT_BITS bit; };
struct FLASH_REGS {
    union FOPT_REG FOPT;
    union FSTDBYWAIT_REG FSTDBYWAIT;
    union FACTIVEWAIT_REG FACTIVEWAIT;
    union FBANKWAIT_REG FBANKWAIT;
    union FOTPWAIT_REG FOTPWAIT;
};
extern volatile struct FLASH_REGS FlashRegs;

/* ------------------------------------------------------------------ CPU timers */
struct TCR_BITS { Uint16 rsvd1:4; Uint16 TSS:1; Uint16 TRB:1; Uint16 rsvd2:4; Uint16 SOFT:1;
                  Uint16 FREE:1; Uint16 rsvd3:2; Uint16 TIE:1; Uint16 TIF:1; };
union TCR_REG { Uint16 all; struct TCR_BITS bit; };
union TPR_REG { Uint16 all; };
union TPRH_REG { Uint16 all; };
struct TIM_REG { Uint16 LSW; Uint16 MSW; };
union TIM_GROUP { Uint32 all; struct TIM_REG half; };
union PRD_GROUP { Uint32 all; struct TIM_REG half; };
struct CPUTIMER_REGS { union TIM_GROUP TIM; union PRD_GROUP PRD; union TCR_REG TCR; Uint16 rsvd1;
                       union TPR_REG TPR; union TPRH_REG TPRH; };
extern volatile struct CPUTIMER_REGS CpuTimer1Regs;

/* ------------------------------------------------------------------ PIE */
struct PIECTRL_BITS { Uint16 ENPIE:1; Uint16 PIEVECT:15; };
union PIECTRL_REG { Uint16 all; struct PIECTRL_BITS bit; };
struct PIEIER_BITS { Uint16 INTx1:1; Uint16 INTx2:1; Uint16 INTx3:1; Uint16 INTx4:1; Uint16 INTx5:1;
                     Uint16 INTx6:1; Uint16 INTx7:1; Uint16 INTx8:1; Uint16 rsvd:8; };
union PIEIER_REG { Uint16 all; struct PIEIER_BITS bit; };
union PIEIFR_REG { Uint16 all; struct PIEIER_BITS bit; };
union PIEACK_REG { Uint16 all; };
struct PIE_CTRL_REGS {
    union PIECTRL_REG PIECTRL;
    union PIEACK_REG PIEACK;
    union PIEIER_REG PIEIER1;  union PIEIFR_REG PIEIFR1;
    union PIEIER_REG PIEIER2;  union PIEIFR_REG PIEIFR2;
    union PIEIER_REG PIEIER3;  union PIEIFR_REG PIEIFR3;
    union PIEIER_REG PIEIER4;  union PIEIFR_REG PIEIFR4;
    union PIEIER_REG PIEIER5;  union PIEIFR_REG PIEIFR5;
    union PIEIER_REG PIEIER6;  union PIEIFR_REG PIEIFR6;
    union PIEIER_REG PIEIER7;  union PIEIFR_REG PIEIFR7;
    union PIEIER_REG PIEIER8;  union PIEIFR_REG PIEIFR8;
    union PIEIER_REG PIEIER9;  union PIEIFR_REG PIEIFR9;
    union PIEIER_REG PIEIER10; union PIEIFR_REG PIEIFR10;
    union PIEIER_REG PIEIER11; union PIEIFR_REG PIEIFR11;
    union PIEIER_REG PIEIER12; union PIEIFR_REG PIEIFR12;
};
extern volatile struct PIE_CTRL_REGS PieCtrlRegs;

typedef void (*PINT)(void);
struct PIE_VECT_TABLE {
    PINT PIE1_RESERVED;
    PINT rsvd_2_37[36];        /* reserved, non-peripheral vectors, group 1.1 .. 1.5 */
    PINT ADCINT;               /* group 1.6 */
    PINT rsvd_39_96[58];
    PINT SCIRXINTA;            /* group 9.1 */
    PINT SCITXINTA;            /* group 9.2 */
    PINT rsvd_99_128[30];
};
extern volatile struct PIE_VECT_TABLE PieVectTable;

/* ------------------------------------------------------------------ GPIO */
struct GPA1_BITS { Uint16 GPIO0:2; Uint16 GPIO1:2; Uint16 GPIO2:2; Uint16 GPIO3:2; Uint16 GPIO4:2;
                   Uint16 GPIO5:2; Uint16 GPIO6:2; Uint16 GPIO7:2; Uint16 GPIO8:2; Uint16 GPIO9:2;
                   Uint16 GPIO10:2; Uint16 GPIO11:2; Uint16 GPIO12:2; Uint16 GPIO13:2; Uint16 GPIO14:2;
                   Uint16 GPIO15:2; };
struct GPA2_BITS { Uint16 GPIO16:2; Uint16 GPIO17:2; Uint16 GPIO18:2; Uint16 GPIO19:2; Uint16 GPIO20:2;
                   Uint16 GPIO21:2; Uint16 GPIO22:2; Uint16 GPIO23:2; Uint16 GPIO24:2; Uint16 GPIO25:2;
                   Uint16 GPIO26:2; Uint16 GPIO27:2; Uint16 GPIO28:2; Uint16 GPIO29:2; Uint16 GPIO30:2;
                   Uint16 GPIO31:2; };
union GPA1_REG { Uint32 all; struct GPA1_BITS bit; };
union GPA2_REG { Uint32 all; struct GPA2_BITS bit; };
struct GPADAT_BITS { Uint16 GPIO0:1; Uint16 GPIO1:1; Uint16 GPIO2:1; Uint16 GPIO3:1; Uint16 GPIO4:1;
                     Uint16 GPIO5:1; Uint16 GPIO6:1; Uint16 GPIO7:1; Uint16 GPIO8:1; Uint16 GPIO9:1;
                     Uint16 GPIO10:1; Uint16 GPIO11:1; Uint16 GPIO12:1; Uint16 GPIO13:1; Uint16 GPIO14:1;
                     Uint16 GPIO15:1; Uint16 GPIO16:1; Uint16 GPIO17:1; Uint16 GPIO18:1; Uint16 GPIO19:1;
                     Uint16 GPIO20:1; Uint16 GPIO21:1; Uint16 GPIO22:1; Uint16 GPIO23:1; Uint16 GPIO24:1;
                     Uint16 GPIO25:1; Uint16 GPIO26:1; Uint16 GPIO27:1; Uint16 GPIO28:1; Uint16 GPIO29:1;
                     Uint16 GPIO30:1; Uint16 GPIO31:1; };
union GPADAT_REG { Uint32 all; struct GPADAT_BITS bit; };
struct GPIO_CTRL_REGS {
    Uint32 GPACTRL;
    union GPA1_REG GPAQSEL1;
    union GPA2_REG GPAQSEL2;
    union GPA1_REG GPAMUX1;
    union GPA2_REG GPAMUX2;
    union GPADAT_REG GPADIR;
    union GPADAT_REG GPAPUD;
};
struct GPIO_DATA_REGS {
    union GPADAT_REG GPADAT;
    union GPADAT_REG GPASET;
    union GPADAT_REG GPACLEAR;
    union GPADAT_REG GPATOGGLE;
};
extern volatile struct GPIO_CTRL_REGS GpioCtrlRegs;
extern volatile struct GPIO_DATA_REGS GpioDataRegs;

/* ------------------------------------------------------------------ ePWM */
struct TBCTL_BITS { Uint16 CTRMODE:2; Uint16 PHSEN:1; Uint16 PRDLD:1; Uint16 SYNCOSEL:2; Uint16 SWFSYNC:1;
                    Uint16 HSPCLKDIV:3; Uint16 CLKDIV:3; Uint16 PHSDIR:1; Uint16 FREE_SOFT:2; };
union TBCTL_REG { Uint16 all; struct TBCTL_BITS bit; };
struct TBPHS_HRPWM_REG { Uint16 TBPHSHR; Uint16 TBPHS; };
union TBPHS_HRPWM_GROUP { Uint32 all; struct TBPHS_HRPWM_REG half; };
struct CMPCTL_BITS { Uint16 LOADAMODE:2; Uint16 LOADBMODE:2; Uint16 SHDWAMODE:1; Uint16 rsvd1:1;
                     Uint16 SHDWBMODE:1; Uint16 rsvd2:1; Uint16 SHDWAFULL:1; Uint16 SHDWBFULL:1; Uint16 rsvd3:6; };
union CMPCTL_REG { Uint16 all; struct CMPCTL_BITS bit; };
struct CMPA_HRPWM_REG { Uint16 CMPAHR; Uint16 CMPA; };
union CMPA_HRPWM_GROUP { Uint32 all; struct CMPA_HRPWM_REG half; };
struct AQCTL_BITS { Uint16 ZRO:2; Uint16 PRD:2; Uint16 CAU:2; Uint16 CAD:2; Uint16 CBU:2; Uint16 CBD:2; Uint16 rsvd:4; };
union AQCTL_REG { Uint16 all; struct AQCTL_BITS bit; };
struct AQSFRC_BITS { Uint16 ACTSFA:2; Uint16 OTSFA:1; Uint16 ACTSFB:2; Uint16 OTSFB:1; Uint16 RLDCSF:2; Uint16 rsvd1:8; };
union AQSFRC_REG { Uint16 all; struct AQSFRC_BITS bit; };
struct AQCSFRC_BITS { Uint16 CSFA:2; Uint16 CSFB:2; Uint16 rsvd1:12; };
union AQCSFRC_REG { Uint16 all; struct AQCSFRC_BITS bit; };
struct DBCTL_BITS { Uint16 OUT_MODE:2; Uint16 POLSEL:2; Uint16 IN_MODE:2; Uint16 rsvd1:10; };
union DBCTL_REG { Uint16 all; struct DBCTL_BITS bit; };
struct TZSEL_BITS { Uint16 CBC1:1; Uint16 CBC2:1; Uint16 CBC3:1; Uint16 CBC4:1; Uint16 CBC5:1; Uint16 CBC6:1;
                    Uint16 rsvd1:2; Uint16 OSHT1:1; Uint16 OSHT2:1; Uint16 OSHT3:1; Uint16 OSHT4:1;
                    Uint16 OSHT5:1; Uint16 OSHT6:1; Uint16 rsvd2:2; };
union TZSEL_REG { Uint16 all; struct TZSEL_BITS bit; };
struct TZCTL_BITS { Uint16 TZA:2; Uint16 TZB:2; Uint16 rsvd:12; };
union TZCTL_REG { Uint16 all; struct TZCTL_BITS bit; };
struct TZ_FLAG_BITS { Uint16 INT:1; Uint16 CBC:1; Uint16 OST:1; Uint16 rsvd2:13; };
union TZ_FLAG_REG { Uint16 all; struct TZ_FLAG_BITS bit; };
struct ETSEL_BITS { Uint16 INTSEL:3; Uint16 INTEN:1; Uint16 rsvd1:4; Uint16 SOCASEL:3; Uint16 SOCAEN:1;
                    Uint16 SOCBSEL:3; Uint16 SOCBEN:1; };
union ETSEL_REG { Uint16 all; struct ETSEL_BITS bit; };
struct ETPS_BITS { Uint16 INTPRD:2; Uint16 INTCNT:2; Uint16 rsvd1:4; Uint16 SOCAPRD:2; Uint16 SOCACNT:2;
                   Uint16 SOCBPRD:2; Uint16 SOCBCNT:2; };
union ETPS_REG { Uint16 all; struct ETPS_BITS bit; };
union PCCTL_REG { Uint16 all; };
struct EPWM_REGS {
    union TBCTL_REG TBCTL;
    Uint16 TBSTS;
    union TBPHS_HRPWM_GROUP TBPHS;
    Uint16 TBCTR;
    Uint16 TBPRD;
    Uint16 rsvd1;
    union CMPCTL_REG CMPCTL;
    union CMPA_HRPWM_GROUP CMPA;
    Uint16 CMPB;
    union AQCTL_REG AQCTLA;
    union AQCTL_REG AQCTLB;
    union AQSFRC_REG AQSFRC;
    union AQCSFRC_REG AQCSFRC;
    union DBCTL_REG DBCTL;
    Uint16 DBRED;
    Uint16 DBFED;
    union TZSEL_REG TZSEL;
    Uint16 rsvd2;
    union TZCTL_REG TZCTL;
    union TZ_FLAG_REG TZEINT;
    union TZ_FLAG_REG TZFLG;
    union TZ_FLAG_REG TZCLR;
    union TZ_FLAG_REG TZFRC;
    union ETSEL_REG ETSEL;
    union ETPS_REG ETPS;
    Uint16 ETFLG;
    Uint16 ETCLR;
    Uint16 ETFRC;
    union PCCTL_REG PCCTL;
};
extern volatile struct EPWM_REGS EPwm1Regs;
extern volatile struct EPWM_REGS EPwm2Regs;
extern volatile struct EPWM_REGS EPwm3Regs;
extern volatile struct EPWM_REGS EPwm4Regs;

/* ------------------------------------------------------------------ ADC */
struct ADCTRL1_BITS { Uint16 rsvd1:4; Uint16 SEQ_CASC:1; Uint16 SEQ_OVRD:1; Uint16 CONT_RUN:1; Uint16 CPS:1;
                      Uint16 ACQ_PS:4; Uint16 SUSMOD:2; Uint16 RESET:1; Uint16 rsvd2:1; };
union ADCTRL1_REG { Uint16 all; struct ADCTRL1_BITS bit; };
struct ADCTRL2_BITS { Uint16 EPWM_SOCB_SEQ2:1; Uint16 rsvd1:1; Uint16 INT_MOD_SEQ2:1; Uint16 INT_ENA_SEQ2:1;
                      Uint16 rsvd2:1; Uint16 SOC_SEQ2:1; Uint16 RST_SEQ2:1; Uint16 EXT_SOC_SEQ1:1;
                      Uint16 EPWM_SOCA_SEQ1:1; Uint16 rsvd3:1; Uint16 INT_MOD_SEQ1:1; Uint16 INT_ENA_SEQ1:1;
                      Uint16 rsvd4:1; Uint16 SOC_SEQ1:1; Uint16 RST_SEQ1:1; Uint16 EPWM_SOCB_SEQ:1; };
union ADCTRL2_REG { Uint16 all; struct ADCTRL2_BITS bit; };
union ADCMAXCONV_REG { Uint16 all; };
struct ADCCHSELSEQ1_BITS { Uint16 CONV00:4; Uint16 CONV01:4; Uint16 CONV02:4; Uint16 CONV03:4; };
union ADCCHSELSEQ1_REG { Uint16 all; struct ADCCHSELSEQ1_BITS bit; };
struct ADCTRL3_BITS { Uint16 SMODE_SEL:1; Uint16 ADCCLKPS:4; Uint16 ADCPWDN:1; Uint16 ADCBGRFDN:2; Uint16 rsvd1:8; };
union ADCTRL3_REG { Uint16 all; struct ADCTRL3_BITS bit; };
struct ADCST_BITS { Uint16 INT_SEQ1:1; Uint16 INT_SEQ2:1; Uint16 SEQ1_BSY:1; Uint16 SEQ2_BSY:1;
                    Uint16 INT_SEQ1_CLR:1; Uint16 INT_SEQ2_CLR:1; Uint16 EOS_BUF1:1; Uint16 EOS_BUF2:1; Uint16 rsvd1:8; };
union ADCST_REG { Uint16 all; struct ADCST_BITS bit; };
struct ADC_REGS {
    union ADCTRL1_REG ADCTRL1;
    union ADCTRL2_REG ADCTRL2;
    union ADCMAXCONV_REG ADCMAXCONV;
    union ADCCHSELSEQ1_REG ADCCHSELSEQ1;
    union ADCTRL3_REG ADCTRL3;
    union ADCST_REG ADCST;
};
struct ADC_RESULT_MIRROR_REGS { Uint16 ADCRESULT0; Uint16 ADCRESULT1; Uint16 ADCRESULT2; Uint16 ADCRESULT3; };
extern volatile struct ADC_REGS AdcRegs;
extern volatile struct ADC_RESULT_MIRROR_REGS AdcMirror;

/* ------------------------------------------------------------------ eQEP */
struct QDECCTL_BITS { Uint16 rsvd1:5; Uint16 QSP:1; Uint16 QIP:1; Uint16 QBP:1; Uint16 QAP:1; Uint16 IGATE:1;
                      Uint16 SWAP:1; Uint16 XCR:1; Uint16 SPSEL:1; Uint16 SOEN:1; Uint16 QSRC:2; };
union QDECCTL_REG { Uint16 all; struct QDECCTL_BITS bit; };
struct QEPCTL_BITS { Uint16 WDE:1; Uint16 UTE:1; Uint16 QCLM:1; Uint16 QPEN:1; Uint16 IEL:2; Uint16 SEL:1;
                     Uint16 SWI:1; Uint16 IEI:2; Uint16 SEI:2; Uint16 PCRM:2; Uint16 FREE_SOFT:2; };
union QEPCTL_REG { Uint16 all; struct QEPCTL_BITS bit; };
union QCAPCTL_REG { Uint16 all; };
union QPOSCTL_REG { Uint16 all; };
union QEINT_REG { Uint16 all; };
struct QFLG_BITS { Uint16 INT:1; Uint16 PCE:1; Uint16 PHE:1; Uint16 QDC:1; Uint16 WTO:1; Uint16 PCU:1;
                   Uint16 PCO:1; Uint16 PCR:1; Uint16 PCM:1; Uint16 SEL:1; Uint16 IEL:1; Uint16 UTO:1; Uint16 rsvd2:4; };
union QFLG_REG { Uint16 all; struct QFLG_BITS bit; };
struct EQEP_REGS {
    Uint32 QPOSCNT;
    Uint32 QPOSINIT;
    Uint32 QPOSMAX;
    Uint32 QPOSCMP;
    Uint32 QPOSILAT;
    union QDECCTL_REG QDECCTL;
    union QEPCTL_REG QEPCTL;
    union QCAPCTL_REG QCAPCTL;
    union QPOSCTL_REG QPOSCTL;
    union QEINT_REG QEINT;
    union QFLG_REG QFLG;
    union QFLG_REG QCLR;
};
extern volatile struct EQEP_REGS EQep1Regs;

/* ------------------------------------------------------------------ SCI */
union SCICCR_REG { Uint16 all; };
struct SCICTL1_BITS { Uint16 RXENA:1; Uint16 TXENA:1; Uint16 SLEEP:1; Uint16 TXWAKE:1; Uint16 rsvd:1;
                      Uint16 SWRESET:1; Uint16 RXERRINTENA:1; Uint16 rsvd1:9; };
union SCICTL1_REG { Uint16 all; struct SCICTL1_BITS bit; };
struct SCICTL2_BITS { Uint16 TXINTENA:1; Uint16 RXBKINTENA:1; Uint16 rsvd:4; Uint16 TXEMPTY:1; Uint16 TXRDY:1;
                      Uint16 rsvd1:8; };
union SCICTL2_REG { Uint16 all; struct SCICTL2_BITS bit; };
struct SCIRXST_BITS { Uint16 rsvd:1; Uint16 RXWAKE:1; Uint16 PE:1; Uint16 OE:1; Uint16 FE:1; Uint16 BRKDT:1;
                      Uint16 RXRDY:1; Uint16 RXERROR:1; };
union SCIRXST_REG { Uint16 all; struct SCIRXST_BITS bit; };
union SCIRXBUF_REG { Uint16 all; };
struct SCIFFTX_BITS { Uint16 TXFFIL:5; Uint16 TXFFIENA:1; Uint16 TXFFINTCLR:1; Uint16 TXFFINT:1; Uint16 TXFFST:5;
                      Uint16 TXFIFOXRESET:1; Uint16 SCIFFENA:1; Uint16 SCIRST:1; };
union SCIFFTX_REG { Uint16 all; struct SCIFFTX_BITS bit; };
struct SCIFFRX_BITS { Uint16 RXFFIL:5; Uint16 RXFFIENA:1; Uint16 RXFFINTCLR:1; Uint16 RXFFINT:1; Uint16 RXFFST:5;
                      Uint16 RXFIFORESET:1; Uint16 RXFFOVRCLR:1; Uint16 RXFFOVF:1; };
union SCIFFRX_REG { Uint16 all; struct SCIFFRX_BITS bit; };
union SCIFFCT_REG { Uint16 all; };
struct SCIPRI_BITS { Uint16 rsvd:3; Uint16 FREE:1; Uint16 SOFT:1; Uint16 rsvd1:3; };
union SCIPRI_REG { Uint16 all; struct SCIPRI_BITS bit; };
struct SCI_REGS {
    union SCICCR_REG SCICCR;
    union SCICTL1_REG SCICTL1;
    Uint16 SCIHBAUD;
    Uint16 SCILBAUD;
    union SCICTL2_REG SCICTL2;
    union SCIRXST_REG SCIRXST;
    Uint16 SCIRXEMU;
    union SCIRXBUF_REG SCIRXBUF;
    Uint16 rsvd1;
    Uint16 SCITXBUF;
    union SCIFFTX_REG SCIFFTX;
    union SCIFFRX_REG SCIFFRX;
    union SCIFFCT_REG SCIFFCT;
    Uint16 rsvd2;
    Uint16 rsvd3;
    union SCIPRI_REG SCIPRI;
};
extern volatile struct SCI_REGS SciaRegs;

#endif
