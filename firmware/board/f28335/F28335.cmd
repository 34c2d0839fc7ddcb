/* pmsm-hil firmware, TMS320F28335, boot to flash (docs/board-f28335.md, "Memory").
 * Link together with C2000Ware's DSP2833x_Headers_nonBIOS.cmd (peripheral register structures).
 *
 *   flash      code_start (0x33FFF6), .text, .cinit, and the load image of ramfuncs
 *   L0-L3      ramfuncs at run time: the time-critical code (.TI.ramfunc: the core objects built
 *              with --ramfunc=on, the ISRs and their helpers, the FPU fastRTS library) and the
 *              constants (.econst, .switch), copied by sysinit_copy_ramfuncs() before use
 *   L4-L7      .ebss: g_fw (the whole core state, ~11.5 k words with the capture buffer) and the rest
 *   M1         stack; M0 .esysmem (no heap)
 * L0-L7 are zero-wait-state SARAM; flash runs at 5 wait states with the prefetch pipeline. */

MEMORY
{
PAGE 0 :   /* program */
   RAML0L3     : origin = 0x008000, length = 0x004000     /* L0-L3 SARAM, 16 k words */
   FLASH       : origin = 0x300000, length = 0x03FF80     /* sectors H..A up to the CSM words */
   CSM_RSVD    : origin = 0x33FF80, length = 0x000076     /* program 0x0000 if the CSM is used */
   BEGIN       : origin = 0x33FFF6, length = 0x000002     /* boot-to-flash entry */
   CSM_PWL_P0  : origin = 0x33FFF8, length = 0x000008     /* CSM password (left erased: 0xFFFF) */
   ADC_CAL     : origin = 0x380080, length = 0x000009     /* TI's ADC_cal in reserved OTP */
   FPUTABLES   : origin = 0x3FEBDC, length = 0x0006A0     /* FPU math tables in boot ROM */
   RESET       : origin = 0x3FFFC0, length = 0x000002

PAGE 1 :   /* data */
   BOOT_RSVD   : origin = 0x000000, length = 0x000050     /* boot ROM stack */
   RAMM0       : origin = 0x000050, length = 0x0003B0
   RAMM1       : origin = 0x000400, length = 0x000400
   RAML4L7     : origin = 0x00C000, length = 0x004000     /* L4-L7 SARAM, 16 k words */
}

SECTIONS
{
   codestart   : > BEGIN,     PAGE = 0
   .text       : > FLASH,     PAGE = 0
   .cinit      : > FLASH,     PAGE = 0
   .pinit      : > FLASH,     PAGE = 0

   ramfuncs    : {
                    *(.TI.ramfunc)
                    *(ramfuncs)
                    -l rts2800_fpu32_fast_supplement_coff.lib (.text)
                    *(.econst)
                    *(.switch)
                 }
                 LOAD = FLASH,
                 RUN = RAML0L3,
                 LOAD_START(_RamfuncsLoadStart),
                 LOAD_SIZE(_RamfuncsLoadSize),
                 RUN_START(_RamfuncsRunStart),
                 PAGE = 0

   .stack      : > RAMM1,     PAGE = 1
   .ebss       : > RAML4L7,   PAGE = 1
   .esysmem    : > RAMM0,     PAGE = 1

   FPUmathTables : > FPUTABLES, PAGE = 0, TYPE = NOLOAD
   .adc_cal    : load = ADC_CAL, PAGE = 0, TYPE = NOLOAD
   .reset      : > RESET,     PAGE = 0, TYPE = DSECT
}
