/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/check.h - a tiny test harness: CHECK*, RUN_TEST, and a summary line.
 * A test file's main() is a list of RUN_TEST(name) followed by `return check_summary();`.
 * check_skip() makes the whole file report "skipped" (exit 77) when nothing failed. */
#ifndef RPIV_TESTS_CHECK_H
#define RPIV_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static int check_failures, check_run, check_skipped, check_current_failed;

/* 1 under `make test`'s valgrind stage (RPIV_MEMCHECK set by run-memcheck-quick): a program
 * whose statistical sweep takes minutes under valgrind runs a few of its cases there (the same
 * code paths, checked for memory errors) and asserts its statistics only in the ASan+UBSan run,
 * which runs every case. */
static inline int check_memcheck(void)
{
    const char *s = getenv("RPIV_MEMCHECK");
    return s && *s && *s != '0';
}

#define CHECK(cond)                                                                                \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);               \
            check_current_failed = 1;                                                              \
        }                                                                                          \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                                      \
    do {                                                                                           \
        double check_a_ = (double)(a), check_b_ = (double)(b), check_t_ = (double)(tol);           \
        if (!(fabs(check_a_ - check_b_) <= check_t_)) {                                            \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, tol %.3g\n",          \
                    __FILE__, __LINE__, #a, check_a_, #b, check_b_, check_t_);                     \
            check_current_failed = 1;                                                              \
        }                                                                                          \
    } while (0)

/* Check a status call succeeded; print rpiv_errmsg() otherwise. */
#define CHECK_OK(call)                                                                             \
    do {                                                                                           \
        int check_st_ = (int)(call);                                                               \
        if (check_st_ != 0) {                                                                      \
            fprintf(stderr, "%s:%d: %s returned %d: %s\n", __FILE__, __LINE__, #call, check_st_,   \
                    rpiv_errmsg());                                                                \
            check_current_failed = 1;                                                              \
        }                                                                                          \
    } while (0)

/* Check a call fails with the given status. */
#define CHECK_FAILS(call, code)                                                                    \
    do {                                                                                           \
        int check_st_ = (int)(call);                                                               \
        if (check_st_ != (int)(code)) {                                                            \
            fprintf(stderr, "%s:%d: %s returned %d, expected %d\n", __FILE__, __LINE__, #call,     \
                    check_st_, (int)(code));                                                       \
            check_current_failed = 1;                                                              \
        }                                                                                          \
    } while (0)

#define RUN_TEST(fn)                                                                               \
    do {                                                                                           \
        check_current_failed = 0;                                                                  \
        check_run++;                                                                               \
        fn();                                                                                      \
        if (check_current_failed) {                                                                \
            check_failures++;                                                                      \
            fprintf(stderr, "FAIL %s\n", #fn);                                                     \
        } else {                                                                                   \
            printf("ok   %s\n", #fn);                                                              \
        }                                                                                          \
    } while (0)

/* Mark the current test as skipped (e.g. shared data absent). */
static inline void check_skip(const char *why)
{
    printf("skip: %s\n", why);
    check_skipped++;
}

static inline int check_summary(void)
{
    printf("%d passed, %d failed\n", check_run - check_failures, check_failures);
    if (check_failures)
        return 1;
    if (check_skipped && check_skipped >= check_run)
        return 77;
    return 0;
}

#endif /* RPIV_TESTS_CHECK_H */
