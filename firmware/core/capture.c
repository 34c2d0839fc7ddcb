#include "capture.h"

/* Scales of the wire (firmware/proto/pmsm_proto.yaml, capture_chunk). */
#define CAP_I_SCALE  0.002f
#define CAP_V_SCALE  0.1f
#define CAP_TH_SCALE 9.587379924285257e-05f
#define CAP_W_SCALE  0.1f

static int16_t cap_i16(float v, float scale)
{
    float x = v / scale;
    if (x > 32767.0f) {
        x = 32767.0f;
    }
    if (x < -32768.0f) {
        x = -32768.0f;
    }
    return (int16_t)(x >= 0.0f ? x + 0.5f : x - 0.5f);
}

static uint16_t cap_u16(float v, float scale)
{
    float x = v / scale + 0.5f;
    if (x > 65535.0f) {
        x = 65535.0f;
    }
    if (x < 0.0f) {
        x = 0.0f;
    }
    return (uint16_t)x;
}

void capture_init(capture_t *c, uint16_t pre)
{
    c->head = 0u;
    c->count = 0u;
    c->pre = (pre < CAPTURE_LEN) ? pre : (uint16_t)(CAPTURE_LEN - 1u);
    c->post_left = 0u;
    c->tick_head = 0u;
    c->state = CAPTURE_ARMED;
}

void capture_record(capture_t *c, uint32_t tick, const capture_sample_t *s)
{
    uint16_t h = c->head;
    if (c->state == CAPTURE_FROZEN) {
        return;
    }
    c->i_a[h] = cap_i16(s->i_a_a, CAP_I_SCALE);
    c->i_b[h] = cap_i16(s->i_b_a, CAP_I_SCALE);
    c->i_c[h] = cap_i16(s->i_c_a, CAP_I_SCALE);
    c->s_abc[h] = s->s_abc;
    c->v_dc[h] = cap_i16(s->v_dc_v, CAP_V_SCALE);
    c->theta[h] = cap_u16(s->theta_e_rad, CAP_TH_SCALE);
    c->omega[h] = cap_i16(s->omega_e_rad_s, CAP_W_SCALE);
    c->head = (uint16_t)((h + 1u) & (CAPTURE_LEN - 1u));
    c->tick_head = tick;
    if (c->count < CAPTURE_LEN) {
        c->count++;
    }
    if (c->state == CAPTURE_TRIGGERED) {
        c->post_left--;
        if (c->post_left == 0u) {
            c->state = CAPTURE_FROZEN;
        }
    }
}

bool capture_trigger(capture_t *c)
{
    if (c->state != CAPTURE_ARMED) {
        return false;
    }
    /* keep at most `pre` samples from before the trigger */
    if (c->count > c->pre) {
        c->count = c->pre;
    }
    c->post_left = (uint16_t)(CAPTURE_LEN - c->count);
    c->state = CAPTURE_TRIGGERED;
    if (c->post_left == 0u) {
        c->state = CAPTURE_FROZEN;
    }
    return true;
}

bool capture_freeze(capture_t *c)
{
    if (c->state == CAPTURE_FROZEN) {
        return false;
    }
    c->state = CAPTURE_FROZEN;
    return true;
}

bool capture_frozen(const capture_t *c)
{
    return c->state == CAPTURE_FROZEN;
}

uint16_t capture_count(const capture_t *c)
{
    return c->count;
}

uint32_t capture_tick0(const capture_t *c)
{
    return c->tick_head - (uint32_t)c->count + 1u;
}

bool capture_get(const capture_t *c, uint16_t i, capture_sample_t *s)
{
    uint16_t k;
    if (i >= c->count) {
        return false;
    }
    k = (uint16_t)((c->head + CAPTURE_LEN - c->count + i) & (CAPTURE_LEN - 1u));
    s->i_a_a = (float)c->i_a[k] * CAP_I_SCALE;
    s->i_b_a = (float)c->i_b[k] * CAP_I_SCALE;
    s->i_c_a = (float)c->i_c[k] * CAP_I_SCALE;
    s->s_abc = c->s_abc[k];
    s->v_dc_v = (float)c->v_dc[k] * CAP_V_SCALE;
    s->theta_e_rad = (float)c->theta[k] * CAP_TH_SCALE;
    s->omega_e_rad_s = (float)c->omega[k] * CAP_W_SCALE;
    return true;
}

void capture_rearm(capture_t *c)
{
    c->count = 0u;
    c->post_left = 0u;
    c->state = CAPTURE_ARMED;
}
