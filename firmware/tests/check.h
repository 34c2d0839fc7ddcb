/* Minimal C unit-test helpers: CHECK(cond, msg), CHECK_NEAR(a, b, tol, msg), CHECK_DONE(). */
#ifndef CHECK_H
#define CHECK_H
#include <stdio.h>
#include <math.h>

static int check_passed = 0;
static int check_failed = 0;

#define CHECK(cond, msg)                                                                           \
    do {                                                                                           \
        if (cond) {                                                                                \
            check_passed++;                                                                        \
        } else {                                                                                   \
            check_failed++;                                                                        \
            printf("FAIL %s:%d: %s\n", __FILE__, __LINE__, msg);                                   \
        }                                                                                          \
    } while (0)

#define CHECK_NEAR(a, b, tol, msg)                                                                 \
    do {                                                                                           \
        double check_a_ = (double)(a), check_b_ = (double)(b);                                     \
        if (fabs(check_a_ - check_b_) <= (double)(tol)) {                                          \
            check_passed++;                                                                        \
        } else {                                                                                   \
            check_failed++;                                                                        \
            printf("FAIL %s:%d: %s: %.9g vs %.9g (tol %.3g)\n", __FILE__, __LINE__, msg, check_a_, \
                   check_b_, (double)(tol));                                                       \
        }                                                                                          \
    } while (0)

#define CHECK_DONE()                                                                               \
    (printf("%d passed, %d failed\n", check_passed, check_failed), check_failed ? 1 : 0)

#endif
