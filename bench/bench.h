/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench.h - what the benchmark programs share: a monotonic clock, medians, peak RSS, a
 * checksum of results, the header line and the result line
 *     case size threads rpiv_ms ref_ms ratio checksum
 * (ratio = rpiv_ms / ref_ms; each program says what its reference is). Header-only. */
#ifndef RPIV_BENCH_H
#define RPIV_BENCH_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

static inline double bench_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int bench_cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* CPU time of the whole process (all threads), s: on a shared machine a steadier measure of
 * work than the wall clock, which counts the time other processes hold the cores. */
static inline double bench_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Median of v[0..n-1] (reordered). */
static inline double bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, bench_cmp);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Peak resident set size of this process, MB. */
static inline double bench_maxrss_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_maxrss / 1024.0;
}

/* FNV-1a of float arrays' bits: identical results give identical checksums. */
static inline uint64_t bench_checksum(uint64_t h, const float *v, size_t n)
{
    const unsigned char *c = (const unsigned char *)v;
    if (!h)
        h = 1469598103934665603ULL;
    for (size_t i = 0; i < n * sizeof *v; i++) {
        h ^= c[i];
        h *= 1099511628211ULL;
    }
    return h;
}

/* Uniform in [0, 1) from the state *s (splitmix64): the benchmarks' fixed-seed inputs. */
static inline double bench_rand(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static inline void bench_header(const char *name, int threads)
{
    char cpu[256] = "unknown", line[512], load[64] = "?";
    FILE *fp = fopen("/proc/cpuinfo", "r");
    while (fp && fgets(line, sizeof line, fp))
        if (!strncmp(line, "model name", 10)) {
            const char *c = strchr(line, ':');
            snprintf(cpu, sizeof cpu, "%.200s", c ? c + 2 : line);
            cpu[strcspn(cpu, "\n")] = 0;
            break;
        }
    if (fp)
        fclose(fp);
    fp = fopen("/proc/loadavg", "r");
    if (fp && fgets(load, sizeof load, fp))
        load[strcspn(load, "\n")] = 0;
    if (fp)
        fclose(fp);
#ifdef __OPTIMIZE__
    const char *opt = "optimised";
#else
    const char *opt = "not optimised";
#endif
    printf("# %s: cpu %s; compiler %s (%s); threads up to %d; load average %s\n", name, cpu,
           __VERSION__, opt, threads, load);
}

static inline void bench_line(const char *cs, int w, int h, int threads, double rpiv_ms,
                              double ref_ms, uint64_t checksum)
{
    char size[32];
    snprintf(size, sizeof size, "%dx%d", w, h);
    printf("%-18s %-10s %7d %10.1f %10.1f %7.2f %016llx\n", cs, size, threads, rpiv_ms, ref_ms,
           ref_ms > 0 ? rpiv_ms / ref_ms : 0.0, (unsigned long long)checksum);
    fflush(stdout);
}

static inline void bench_columns(void)
{
    printf("%-18s %-10s %7s %10s %10s %7s %s\n", "case", "size", "threads", "rpiv_ms", "ref_ms",
           "ratio", "checksum");
}

#endif /* RPIV_BENCH_H */
