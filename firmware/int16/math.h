/* Declarations only, for `make -C firmware int16`: the core compiled for a target whose int is
 * 16 bits, as the C28x's (clang, msp430), which has no C library here. */
#ifndef INT16_CHECK_MATH_H
#define INT16_CHECK_MATH_H
float sinf(float x);
float cosf(float x);
float tanf(float x);
float atanf(float x);
float atan2f(float y, float x);
float sqrtf(float x);
float fabsf(float x);
float expf(float x);
float logf(float x);
float floorf(float x);
float ceilf(float x);
float fmodf(float x, float y);
float fminf(float x, float y);
float fmaxf(float x, float y);
float powf(float x, float y);
#define NAN         (__builtin_nanf(""))
#define INFINITY    (__builtin_inff())
#define isnan(x)    __builtin_isnan(x)
#define isfinite(x) __builtin_isfinite(x)
#define isinf(x)    __builtin_isinf(x)
#endif
