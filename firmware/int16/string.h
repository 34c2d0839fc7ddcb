/* Declarations only, for `make -C firmware int16` (see math.h beside it). */
#ifndef INT16_CHECK_STRING_H
#define INT16_CHECK_STRING_H
#include <stddef.h>
void *memset(void *s, int c, size_t n);
void *memcpy(void *dst, const void *src, size_t n);
void *memmove(void *dst, const void *src, size_t n);
int memcmp(const void *a, const void *b, size_t n);
#endif
