/* The angle slot (angle_slot.h): dispatch to today's occupant, the encoder. */
#include "angle_slot.h"

#include <string.h>

bool angle_src_known(uint16_t src)
{
    return src == ANGLE_SRC_ENCODER;
}

void angle_init(angle_t *a, const angle_cfg_t *cfg)
{
    a->cfg = *cfg;
    if (!angle_src_known(cfg->src)) {
        a->cfg.src = ANGLE_SRC_ENCODER;
    }
    memset(&a->last, 0, sizeof(a->last));
}

/* The encoder: its raw-count angle and its observer's speed. */
static void step_encoder(const angle_in_t *in, angle_out_t *out)
{
    if (in->enc == NULL) {
        memset(out, 0, sizeof(*out));
        out->valid = false;
        return;
    }
    out->theta_e_rad = in->enc->theta_e_rad;
    out->omega_e_rad_s = in->enc->omega_e_rad_s;
    out->omega_m_rad_s = in->enc->omega_m_rad_s;
    out->speed_rpm = in->enc->speed_rpm;
    out->valid = true;
}

void angle_step(angle_t *a, const angle_in_t *in, angle_out_t *out)
{
    switch (a->cfg.src) {
    case ANGLE_SRC_ENCODER:
    default:
        step_encoder(in, out);
        break;
    }
    a->last = *out;
}
