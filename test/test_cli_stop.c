/*
 * test_cli_stop.c — how `anistar mesh` (examples/anistar.c, docs/cli.md) stops and what
 * it says while it runs, the tool run as a separate process:
 *  - SIGINT and SIGTERM during a long run: exit 3 within a few seconds, every output
 *    written (the OFF reads back with the library's own reader and matches --stats, which
 *    says "complete": false and "stop_reason": "requested"), stderr's last line names the
 *    signal; a second signal kills the process;
 *  - outputs that cannot be written are refused before anything is meshed (exit 1 at
 *    once, one line naming the path, no other output created, an existing one untouched);
 *  - progress on a file or pipe: newline-terminated lines, first at 1 s, never a \r; on a
 *    terminal (a pseudo-terminal here): one line rewritten with \r;
 *  - --max-stall: 1 ends a run that has inconsistencies as a stall (exit 3, stop_reason
 *    "stall", one line even with --quiet); -1 and 1.5 are usage errors.
 * Every run is bounded: the long one (a torus at r0 0.02, about 20 s to finish) is always
 * stopped by a signal or --max-seconds.
 */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */

#include "test_util.h"

#include "io/meshio.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"
#define TMP AS_TEST_BUILD_DIR "/anistar_clistop_"

/* The long run: well over 10 s to finish on any machine we test on. */
#define LONG_RUN "mesh", "--builtin", "torus", "--metric", "curvature", "--r0", "0.02"

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void sleep_s(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

/* Start the tool with args (NULL-terminated, without argv[0]): stdout to /dev/null,
 * stderr to the file err_path (or to the descriptor err_fd when err_path is NULL), SIGINT
 * and SIGTERM at their default actions (a test run from a script in the background would
 * otherwise pass them on ignored). Returns the pid. */
static pid_t spawn(const char *const *args, const char *err_path, int err_fd) {
    const char *argv[64];
    int n = 0;
    argv[n++] = TOOL;
    for (int i = 0; args[i]; i++) {
        assert_true(n < 63);
        argv[n++] = args[i];
    }
    argv[n] = NULL;
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fe = err_path ? open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644) : err_fd;
        int fo = open("/dev/null", O_WRONLY);
        if (fe < 0 || fo < 0) _exit(126);
        dup2(fo, 1);
        dup2(fe, 2);
        signal(SIGINT, SIG_DFL);
        signal(SIGTERM, SIG_DFL);
        execv(TOOL, (char *const *)argv);
        _exit(127);
    }
    return pid;
}

/* Wait at most timeout seconds for pid; kill it and fail past that. Returns the raw
 * wait status. */
static int wait_for(pid_t pid, double timeout) {
    double t0 = now_s();
    for (;;) {
        int wst = 0;
        pid_t r = waitpid(pid, &wst, WNOHANG);
        assert_true(r >= 0);
        if (r == pid) return wst;
        if (now_s() - t0 > timeout) {
            kill(pid, SIGKILL);
            waitpid(pid, &wst, 0);
            fail_msg("the tool did not exit within %.0f s", timeout);
        }
        sleep_s(0.02);
    }
}

/* The last line of text (without its '\n') copied into line. */
static void last_line(const char *text, char *line, size_t cap) {
    size_t len = strlen(text);
    while (len > 0 && text[len - 1] == '\n') len--;
    size_t start = len;
    while (start > 0 && text[start - 1] != '\n') start--;
    size_t k = len - start < cap - 1 ? len - start : cap - 1;
    memcpy(line, text + start, k);
    line[k] = '\0';
}

/* The JSON string value of key is exactly want. */
static void assert_json_string(const char *json, const char *key, const char *want) {
    const char *v = tu_json_value(json, key);
    if (!v) fail_msg("--stats lacks \"%s\"", key);
    size_t n = strlen(want);
    if (v[0] != '"' || strncmp(v + 1, want, n) || v[n + 1] != '"')
        fail_msg("--stats \"%s\" is not \"%s\": %.40s", key, want, v);
}

/* Wait (up to limit seconds) until the progress lines in file err report at least min
 * vertices: a run well under way, whatever the load of the machine (a fixed delay found
 * no consistent facet yet under ASan on a busy machine). */
static void wait_for_vertices(const char *err, long min, double limit) {
    double t0 = now_s();
    while (now_s() - t0 < limit) {
        char *e = tu_read_file(err);
        long best = 0;
        for (const char *p = e; p && (p = strstr(p, "anistar: mesh: ")) != NULL; p += 15) {
            long v = strtol(p + 15, NULL, 10);
            if (v > best) best = v;
        }
        free(e);
        if (best >= min) return;
        sleep_s(0.02);
    }
    fail_msg("no progress line reached %ld vertices in %.0f s", min, limit);
}

/* Stop the long run with sig once it is well under way. */
static void stop_by_signal(int sig, const char *name) {
    const char *off = TMP "sig.off", *sol = TMP "sig.sol", *json = TMP "sig.json",
               *err = TMP "sig.err";
    unlink(off), unlink(sol), unlink(json), unlink(err);
    const char *args[] = {LONG_RUN, "-o", off, "--sol", sol, "--stats", json, NULL};
    pid_t pid = spawn(args, err, -1);
    wait_for_vertices(err, 2000, 60);
    double t0 = now_s();
    assert_int_equal(kill(pid, sig), 0);
    int wst = wait_for(pid, 15);
    double dt = now_s() - t0;
    char *e = tu_read_file(err);
    assert_non_null(e);
    if (!WIFEXITED(wst) || WEXITSTATUS(wst) != 3)
        fail_msg("%s: not exit 3 (wait status %d), stderr '%s'", name, wst, e);
    if (dt > 5) fail_msg("%s: exit %.1f s after the signal", name, dt);

    /* stderr: progress lines, then one line naming the signal */
    char line[1024];
    last_line(e, line, sizeof line);
    char want[64];
    snprintf(want, sizeof want, "anistar: stopped by %s: ", name);
    if (strncmp(line, want, strlen(want))) fail_msg("last line '%s' lacks '%s'", line, want);
    assert_non_null(strstr(line, " facets written, "));
    assert_null(strchr(e, '\r')); /* stderr is a file: no rewritten line */
    for (const char *p = e; *p;) {
        const char *nl = strchr(p, '\n');
        assert_non_null(nl); /* every line ended */
        if (strncmp(p, "anistar: mesh: ", 15) && strncmp(p, want, strlen(want)))
            fail_msg("unexpected stderr line '%.*s'", (int)(nl - p), p);
        p = nl + 1;
    }

    /* --stats: an incomplete run stopped on request, the new keys present */
    char *js = tu_read_file(json);
    assert_non_null(js);
    assert_int_equal(tu_json_bool(js, "complete"), 0);
    assert_json_string(js, "stop_reason", "requested");
    double nv = tu_json_number(js, "vertices"), nf = tu_json_number(js, "facets");
    assert_true(nv > 0 && nf > 0);
    assert_true(tu_json_number(js, "components") >= 0);
    assert_true(tu_json_number(js, "peak_bytes") > 0);
    assert_true(tu_json_number(js, "stall_max") >= 0);
    const char *est = tu_json_value(js, "estimate");
    assert_non_null(est);
    assert_true(tu_json_number(est, "vertices") >= 0 && tu_json_number(est, "bytes") >= 0);
    const char *ins = tu_json_value(js, "insertions");
    assert_non_null(ins);
    assert_true(tu_json_number(ins, "topology") >= 0);
    const char *causes = tu_json_value(ins, "rule1_causes");
    assert_non_null(causes);
    double sum = tu_json_number(causes, "size") + tu_json_number(causes, "distortion") +
                 tu_json_number(causes, "approximation") + tu_json_number(causes, "feature");
    assert_true(sum == tu_json_number(ins, "rule1"));
    const char *par = tu_json_value(js, "parameters");
    assert_non_null(par);
    assert_true(tu_json_number(par, "max_stall") == 0);
    assert_true(tu_json_number(par, "max_vertices") == 1000000); /* the default */
    /* and the counts of the line are those of the JSON */
    snprintf(want, sizeof want, ": %.0f vertices, %.0f facets written, ", nv, nf);
    if (!strstr(line, want)) fail_msg("'%s' lacks '%s'", line, want);

    /* the OFF reads back with the library's reader, the same counts */
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    as_trimesh tm;
    as_trimesh_init(&tm);
    if (as_mesh_read(ctx, off, &tm) != ANISTAR_OK) fail_msg("%s", anistar_last_error(ctx));
    assert_true((double)tm.nv == nv);
    assert_true((double)tm.nt == nf);
    as_trimesh_free(ctx, &tm);
    anistar_context_free(ctx);
    /* and the .sol holds one tensor per vertex */
    char *so = tu_read_file(sol);
    assert_non_null(so);
    const char *p = strstr(so, "SolAtVertices");
    assert_non_null(p);
    assert_true((double)strtol(p + strlen("SolAtVertices"), NULL, 10) == nv);
    free(so);
    free(js);
    free(e);
    unlink(off), unlink(sol), unlink(json), unlink(err);
}

static void test_sigint(void **state) {
    (void)state;
    stop_by_signal(SIGINT, "SIGINT");
}

static void test_sigterm(void **state) {
    (void)state;
    stop_by_signal(SIGTERM, "SIGTERM");
}

/* A second signal kills the process (the handler put the default action back): SIGINT
 * sent again and again from 1.5 s on, until the tool is gone. */
static void test_second_signal(void **state) {
    (void)state;
    const char *off = TMP "k.off", *err = TMP "k.err";
    const char *args[] = {LONG_RUN, "-o", off, NULL};
    pid_t pid = spawn(args, err, -1);
    sleep_s(1.5);
    double t0 = now_s();
    int wst = 0;
    for (;;) {
        kill(pid, SIGINT);
        pid_t r = waitpid(pid, &wst, WNOHANG);
        assert_true(r >= 0);
        if (r == pid) break;
        if (now_s() - t0 > 15) {
            kill(pid, SIGKILL);
            waitpid(pid, &wst, 0);
            fail_msg("the tool did not exit within 15 s of SIGINTs");
        }
        sleep_s(0.001);
    }
    if (!WIFSIGNALED(wst) || WTERMSIG(wst) != SIGINT)
        fail_msg("not killed by SIGINT (wait status %d)", wst);
    unlink(off), unlink(err);
}

/* An output that cannot be written: exit 1 at once (the long run is not started), one line
 * naming the path and the reason, and no output file left behind. */
static void refused(const char *const *args, const char *path, const char *reason,
                    const char *const *others) {
    for (int i = 0; others[i]; i++) unlink(others[i]);
    tu_run_result *r = test_malloc(sizeof *r);
    double t0 = now_s();
    tu_run(TOOL, args, r);
    double dt = now_s() - t0;
    if (r->status != 1) fail_msg("%s: exit %d, stderr '%s'", path, r->status, r->err);
    tu_assert_one_line(r);
    if (!strstr(r->err, path) || !strstr(r->err, reason))
        fail_msg("'%s' lacks '%s' or '%s'", r->err, path, reason);
    if (dt > 3) fail_msg("%s: refused only after %.1f s", path, dt);
    assert_string_equal(r->out, "");
    for (int i = 0; others[i]; i++)
        if (access(others[i], F_OK) == 0) fail_msg("%s was created", others[i]);
    test_free(r);
}

static void test_unwritable_output(void **state) {
    (void)state;
    const char *off = TMP "u.off", *json = TMP "u.json", *sol = TMP "u.sol";
    /* a directory that does not exist, after a writable -o and before --stats */
    {
        const char *args[] = {LONG_RUN, "-o", off, "-o", "/nonexistent_dir/x.off",
                              "--stats", json, NULL};
        const char *others[] = {off, json, NULL};
        refused(args, "/nonexistent_dir/x.off", strerror(ENOENT), others);
    }
    /* --stats naming a directory */
    {
        const char *args[] = {LONG_RUN, "-o", off, "--sol", sol, "--stats", "/tmp", NULL};
        const char *others[] = {off, sol, NULL};
        refused(args, "'/tmp'", strerror(EISDIR), others);
    }
    /* --stats in a read-only directory (root writes there anyway) */
    char dir[] = "/tmp/anistar_clistop_ro_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[64];
    snprintf(path, sizeof path, "%s/s.json", dir);
    assert_int_equal(chmod(dir, 0555), 0);
    if (geteuid() == 0) {
        print_message("skipped the read-only directory case: running as root, which may "
                      "write into any directory\n");
    } else {
        const char *args[] = {LONG_RUN, "-o", off, "--stats", path, NULL};
        const char *others[] = {off, NULL};
        refused(args, path, strerror(EACCES), others);
        assert_true(access(path, F_OK) != 0);
    }
    chmod(dir, 0755);
    rmdir(dir);
    /* an existing output is checked without being truncated */
    FILE *f = fopen(off, "w");
    assert_non_null(f);
    fputs("keep me\n", f);
    fclose(f);
    {
        const char *args[] = {LONG_RUN, "-o", off, "--sol", "/nonexistent_dir/x.sol", NULL};
        const char *others[] = {json, NULL};
        refused(args, "/nonexistent_dir/x.sol", strerror(ENOENT), others);
    }
    char *kept = tu_read_file(off);
    assert_non_null(kept);
    assert_string_equal(kept, "keep me\n");
    free(kept);
    unlink(off);
}

/* Progress on a file: newline-terminated "anistar: mesh:" lines, the first after 1 s and
 * the next not before 11 s, never a \r; then the run's line (--max-seconds). */
static void test_progress_file(void **state) {
    (void)state;
    const char *off = TMP "p.off";
    const char *args[] = {LONG_RUN, "--max-seconds", "3", "-o", off, NULL};
    tu_run_result *r = test_malloc(sizeof *r);
    tu_run(TOOL, args, r);
    if (r->status != 3) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    assert_null(strchr(r->err, '\r'));
    size_t len = strlen(r->err);
    assert_true(len > 0 && r->err[len - 1] == '\n');
    int progress = 0, other = 0;
    for (const char *p = r->err; *p;) {
        const char *nl = strchr(p, '\n');
        assert_non_null(nl);
        if (!strncmp(p, "anistar: mesh: ", 15)) {
            progress++;
            if (other) fail_msg("a progress line after the run's line: '%s'", r->err);
            if (!strstr(p, " vertices, ") || !strstr(p, " inconsistent facets, ") ||
                !strstr(p, " s"))
                fail_msg("malformed progress line '%.*s'", (int)(nl - p), p);
            char *end;
            double v = strtod(p + 15, &end);
            assert_true(end > p + 15 && v > 0);
        } else {
            assert_true(!strncmp(p, "anistar: incomplete (max_seconds): ", 35));
            other++;
        }
        p = nl + 1;
    }
    assert_int_equal(other, 1);
    if (progress != 1) fail_msg("%d progress lines in about 3 s: '%s'", progress, r->err);

    /* --quiet: the run's line only */
    const char *quiet[] = {LONG_RUN, "--max-seconds", "1.5", "--quiet", "-o", off, NULL};
    tu_run(TOOL, quiet, r);
    if (r->status != 3) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    tu_assert_one_line(r);
    assert_non_null(strstr(r->err, "anistar: incomplete (max_seconds): "));
    assert_non_null(strstr(r->err, "mesher: stopped at max_seconds"));
    test_free(r);
    unlink(off);
}

/* Progress on a terminal: one line rewritten with \r (no newline between the rewrites),
 * ended by a newline before the run's line. */
static void test_progress_tty(void **state) {
    (void)state;
    const char *off = TMP "t.off";
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0) {
        print_message("skipped: no pseudo-terminal (%s)\n", strerror(errno));
        return;
    }
    assert_int_equal(grantpt(master), 0);
    assert_int_equal(unlockpt(master), 0);
    const char *name = ptsname(master);
    assert_non_null(name);
    int slave = open(name, O_RDWR | O_NOCTTY);
    assert_true(slave >= 0);
    const char *args[] = {LONG_RUN, "--max-seconds", "2.5", "-o", off, NULL};
    pid_t pid = spawn(args, NULL, slave);
    close(slave);
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap);
    assert_non_null(buf);
    double t0 = now_s();
    int wst = 0, exited = 0;
    for (;;) {
        struct pollfd pfd = {master, POLLIN, 0};
        if (poll(&pfd, 1, 50) > 0) {
            ssize_t k = read(master, buf + n, cap - 1 - n);
            if (k > 0) n += (size_t)k;
            else if (exited) break; /* EIO: every slave closed */
        } else if (exited) {
            break;
        }
        if (!exited && waitpid(pid, &wst, WNOHANG) == pid) exited = 1;
        if (!exited && now_s() - t0 > 20) {
            kill(pid, SIGKILL);
            waitpid(pid, &wst, 0);
            fail_msg("the tool did not exit within 20 s");
        }
        if (n + 1 >= cap) break;
    }
    buf[n] = '\0';
    close(master);
    if (!WIFEXITED(wst) || WEXITSTATUS(wst) != 3)
        fail_msg("not exit 3 (wait status %d): '%s'", wst, buf);
    /* at least two rewrites, nothing but \r between them (the terminal turns "\n" into
     * "\r\n", so a newline shows as '\n') */
    const char *first = strstr(buf, "\ranistar: mesh: "), *last = first;
    if (!first) fail_msg("no rewritten progress line: '%s'", buf);
    int count = 0;
    for (const char *p = first; (p = strstr(p, "\ranistar: mesh: ")); p++) {
        last = p;
        count++;
    }
    if (count < 2) fail_msg("%d progress rewrites in 2.5 s: '%s'", count, buf);
    for (const char *p = first; p < last; p++)
        if (*p == '\n') fail_msg("a newline between progress rewrites: '%s'", buf);
    const char *nl = strchr(last, '\n');
    assert_non_null(nl);
    assert_non_null(strstr(nl, "anistar: incomplete (max_seconds): "));
    free(buf);
    unlink(off);
}

/* --max-stall 1 on a run with inconsistencies: a stall (exit 3), said even with --quiet;
 * negative or fractional values are usage errors. */
static void test_max_stall(void **state) {
    (void)state;
    const char *off = TMP "m.off", *json = TMP "m.json";
    unlink(off), unlink(json);
    const char *args[] = {"mesh", "--builtin", "torus", "--r0", "0.2", "--gamma0", "2",
                          "--max-stall", "1", "--quiet", "-o", off, "--stats", json, NULL};
    tu_run_result *r = test_malloc(sizeof *r);
    tu_run(TOOL, args, r);
    if (r->status != 3) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    tu_assert_one_line(r);
    assert_non_null(strstr(r->err, "anistar: incomplete (stall): "));
    assert_non_null(strstr(r->err, "mesher: stalled"));
    char *js = tu_read_file(json);
    assert_non_null(js);
    assert_int_equal(tu_json_bool(js, "complete"), 0);
    assert_json_string(js, "stop_reason", "stall");
    assert_true(tu_json_number(js, "inconsistent_facets") > 0);
    assert_true(tu_json_number(js, "stall_max") >= 1);
    const char *par = tu_json_value(js, "parameters");
    assert_non_null(par);
    assert_true(tu_json_number(par, "max_stall") == 1);
    free(js);
    assert_true(access(off, F_OK) == 0);
    unlink(off), unlink(json);

    const char *bad[] = {"-1", "1.5", "x"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *a[] = {"mesh", "--builtin", "sphere", "--max-stall", bad[i], "-o", off, NULL};
        tu_run(TOOL, a, r);
        if (r->status != 2) fail_msg("--max-stall %s: exit %d, '%s'", bad[i], r->status, r->err);
        tu_assert_one_line(r);
        assert_non_null(strstr(r->err, "max"));
        assert_true(access(off, F_OK) != 0);
    }
    test_free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sigint),
        cmocka_unit_test(test_sigterm),
        cmocka_unit_test(test_second_signal),
        cmocka_unit_test(test_unwritable_output),
        cmocka_unit_test(test_progress_file),
        cmocka_unit_test(test_progress_tty),
        cmocka_unit_test(test_max_stall),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
