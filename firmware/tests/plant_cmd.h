/* Helpers shared by the plant's C tests: the default configuration and a forced-state command. */
#ifndef PLANT_CMD_H
#define PLANT_CMD_H
#include <string.h>

#include "plant.h"

static inline void cfg_base(plant_cfg_t *c)
{
    plant_cfg_default(c); /* paper A's IPMSM, 540 V, Ts 50 us, ideal inverter and sensors */
}

static inline void cmd_set(fw_cmd_t *c, int sa, int sb, int sc, bool on, double load)
{
    memset(c, 0, sizeof *c);
    c->mode = FW_CMD_STATES;
    c->s_a = (uint16_t)sa;
    c->s_b = (uint16_t)sb;
    c->s_c = (uint16_t)sc;
    c->pwm_on = on;
    c->load_nm = (float)load;
}

#endif
