/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/child_rss.h - the peak RSS of a piece of work, measured in a child process (fork,
 * wait4's ru_maxrss), shared by test_fuzz_regressions and test_fuzz_rss. */
#ifndef RPIV_TESTS_CHILD_RSS_H
#define RPIV_TESTS_CHILD_RSS_H

#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

/* Run fn(arg) in a child that exits with its return value (0..255): the child's peak RSS in
 * KiB, its exit code in *code (may be NULL); -1 if it could not run or did not exit. */
static inline long ti_child_rss_kb(int (*fn)(void *), void *arg, int *code)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0)
        _exit(fn(arg));
    int status = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    if (pid < 0 || wait4(pid, &status, 0, &ru) != pid || !WIFEXITED(status))
        return -1;
    if (code)
        *code = WEXITSTATUS(status);
    return ru.ru_maxrss;
}

#endif /* RPIV_TESTS_CHILD_RSS_H */
