/* HOST-ONLY STUB of C2000Ware's DSP2833x_EPwm_defines.h (common/include): the field values the
 * board code uses, to compile-check it on a PC (make hostcheck). Never used by the real build. */
#ifndef DSP2833x_EPWM_DEFINES_H
#define DSP2833x_EPWM_DEFINES_H

#define TB_COUNT_UP     0x0
#define TB_COUNT_UPDOWN 0x2
#define TB_FREEZE       0x3
#define TB_DISABLE      0x0
#define TB_ENABLE       0x1
#define TB_SHADOW       0x0
#define TB_SYNC_IN      0x0
#define TB_CTR_ZERO     0x1
#define TB_SYNC_DISABLE 0x3
#define TB_DIV1         0x0
#define TB_UP           0x1
#define CC_CTR_ZERO     0x0
#define CC_SHADOW       0x0
#define AQ_CLEAR        0x1
#define AQ_SET          0x2
#define DB_FULL_ENABLE  0x3
#define DB_ACTV_HIC     0x2
#define DBA_ALL         0x0
#define TZ_FORCE_LO     0x2
#define ET_CTR_ZERO     0x1
#define ET_CTRD_CMPB    0x7
#define ET_1ST          0x1

#endif
