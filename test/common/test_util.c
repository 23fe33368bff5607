#include "test_util.h"

#include <math.h>
#include <pthread.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

/* The library calls the allocator from its threads at once (anistar.h): one lock for the
 * counters of every tu_alloc (tests only). */
static pthread_mutex_t tu_alloc_lock = PTHREAD_MUTEX_INITIALIZER;

static void *tu_alloc_locked(tu_alloc *a, void *ptr, size_t old_size, size_t new_size);

static void *tu_alloc_fn(void *user, void *ptr, size_t old_size, size_t new_size) {
    pthread_mutex_lock(&tu_alloc_lock);
    void *q = tu_alloc_locked(user, ptr, old_size, new_size);
    pthread_mutex_unlock(&tu_alloc_lock);
    return q;
}

static void *tu_alloc_locked(tu_alloc *a, void *ptr, size_t old_size, size_t new_size) {
    if (new_size == 0) {
        if (ptr) {
            a->live_blocks--;
            a->live_bytes -= old_size;
            free(ptr);
        }
        return NULL;
    }
    if (!ptr || new_size > old_size) {
        long n = a->count++;
        if (a->fail_after >= 0 && n >= a->fail_after) {
            a->failures++;
            return NULL;
        }
    }
    void *q = realloc(ptr, new_size);
    if (!q) return NULL;
    if (!ptr) a->live_blocks++;
    a->live_bytes += new_size - (ptr ? old_size : 0);
    if (a->live_bytes > a->peak_bytes) a->peak_bytes = a->live_bytes;
    return q;
}

void tu_alloc_init(tu_alloc *a, long fail_after) {
    a->fail_after = fail_after;
    a->count = 0;
    a->live_blocks = 0;
    a->live_bytes = 0;
    a->peak_bytes = 0;
    a->failures = 0;
}

anistar_allocator tu_allocator(tu_alloc *a) {
    anistar_allocator al = {tu_alloc_fn, a};
    return al;
}

uint64_t tu_rng_u64(tu_rng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

double tu_rng_unit(tu_rng *r) { return (double)(tu_rng_u64(r) >> 11) * 0x1.0p-53; }

double tu_rng_range(tu_rng *r, double lo, double hi) { return lo + (hi - lo) * tu_rng_unit(r); }

double tu_rng_gauss(tu_rng *r) {
    double u = tu_rng_unit(r), v = tu_rng_unit(r);
    return sqrt(-2 * log(1 - u)) * cos(6.283185307179586 * v);
}

void tu_random_rotation(tu_rng *r, double q[9]) {
    double a = tu_rng_gauss(r), b = tu_rng_gauss(r), c = tu_rng_gauss(r), d = tu_rng_gauss(r);
    double n = sqrt(a * a + b * b + c * c + d * d);
    a /= n;
    b /= n;
    c /= n;
    d /= n;
    q[0] = a * a + b * b - c * c - d * d;
    q[1] = 2 * (b * c - a * d);
    q[2] = 2 * (b * d + a * c);
    q[3] = 2 * (b * c + a * d);
    q[4] = a * a - b * b + c * c - d * d;
    q[5] = 2 * (c * d - a * b);
    q[6] = 2 * (b * d - a * c);
    q[7] = 2 * (c * d + a * b);
    q[8] = a * a - b * b - c * c + d * d;
}

double *tu_pts_alloc(int n) {
    double *p = malloc(3 * (size_t)n * sizeof *p);
    assert_non_null(p);
    return p;
}

double *tu_pts_cube(tu_rng *r, int n) {
    double *p = tu_pts_alloc(n);
    for (int i = 0; i < 3 * n; i++) p[i] = tu_rng_range(r, -1, 1);
    return p;
}

double *tu_pts_sphere(tu_rng *r, int n) {
    double *p = tu_pts_alloc(n);
    for (int i = 0; i < n; i++) {
        double x = tu_rng_gauss(r), y = tu_rng_gauss(r), z = tu_rng_gauss(r);
        double s = sqrt(x * x + y * y + z * z);
        p[3 * i] = x / s;
        p[3 * i + 1] = y / s;
        p[3 * i + 2] = z / s;
    }
    return p;
}

double *tu_pts_torus(tu_rng *r, int n, double R, double rr) {
    double *p = tu_pts_alloc(n);
    for (int i = 0; i < n; i++) {
        double a = tu_rng_range(r, 0, 6.283185307179586);
        double b = tu_rng_range(r, 0, 6.283185307179586);
        p[3 * i] = (R + rr * cos(b)) * cos(a);
        p[3 * i + 1] = (R + rr * cos(b)) * sin(a);
        p[3 * i + 2] = rr * sin(b);
    }
    return p;
}

static void tu_slurp(int fd, char *buf, size_t cap) {
    size_t n = 0;
    lseek(fd, 0, SEEK_SET);
    for (;;) {
        ssize_t r = read(fd, buf + n, cap - 1 - n);
        if (r <= 0) break;
        n += (size_t)r;
        if (n + 1 >= cap) break;
    }
    buf[n] = '\0';
}

void tu_run(const char *program, const char *const *args, tu_run_result *res) {
    char outname[] = "/tmp/anistar_run_out_XXXXXX", errname[] = "/tmp/anistar_run_err_XXXXXX";
    int fo = mkstemp(outname), fe = mkstemp(errname);
    assert_true(fo >= 0 && fe >= 0);
    const char *argv[64];
    int n = 0;
    argv[n++] = program;
    for (int i = 0; args[i]; i++) {
        assert_true(n < 63);
        argv[n++] = args[i];
    }
    argv[n] = NULL;
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        dup2(fo, 1);
        dup2(fe, 2);
        execv(program, (char *const *)argv);
        _exit(127);
    }
    int wst = 0;
    assert_true(waitpid(pid, &wst, 0) == pid);
    res->status = WIFEXITED(wst) ? WEXITSTATUS(wst) : -1;
    tu_slurp(fo, res->out, sizeof res->out);
    tu_slurp(fe, res->err, sizeof res->err);
    close(fo);
    close(fe);
    unlink(outname);
    unlink(errname);
}

void tu_assert_one_line(const tu_run_result *r) {
    size_t len = strlen(r->err);
    if (!(len > 10 && r->err[len - 1] == '\n' && strchr(r->err, '\n') == r->err + len - 1 &&
          !strncmp(r->err, "anistar: ", 9)))
        fail_msg("stderr is not one 'anistar: ...' line: '%s'", r->err);
}

char *tu_read_file(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap);
    assert_non_null(buf);
    for (;;) {
        if (n + 1 >= cap) {
            cap *= 2;
            buf = realloc(buf, cap);
            assert_non_null(buf);
        }
        size_t r = fread(buf + n, 1, cap - 1 - n, f);
        if (r == 0) break;
        n += r;
    }
    buf[n] = '\0';
    fclose(f);
    return buf;
}

const char *tu_json_value(const char *json, const char *key) {
    /* design: only the members of the object json starts with (not nested ones, whose
     * keys may repeat: "optimize" is a key of "seconds" too); a text that does not start
     * with an object is searched as a whole */
    const char *p = json;
    while (*p == ' ' || *p == '\n' || *p == '\t' || *p == '\r') p++;
    size_t kl = strlen(key);
    if (*p != '{') {
        char pat[64];
        snprintf(pat, sizeof pat, "\"%s\":", key);
        const char *q = strstr(json, pat);
        if (!q) return NULL;
        q += strlen(pat);
        while (*q == ' ') q++;
        return q;
    }
    int depth = 0;
    for (; *p; p++) {
        if (*p == '"') {
            const char *b = ++p;
            while (*p && *p != '"') p += (*p == '\\' && p[1]) ? 2 : 1;
            if (!*p) return NULL;
            const char *e = p; /* the closing quote */
            const char *q = p + 1;
            while (*q == ' ' || *q == '\n' || *q == '\t' || *q == '\r') q++;
            if (depth == 1 && *q == ':' && (size_t)(e - b) == kl && !strncmp(b, key, kl)) {
                q++;
                while (*q == ' ' || *q == '\n' || *q == '\t' || *q == '\r') q++;
                return q;
            }
        } else if (*p == '{' || *p == '[') {
            depth++;
        } else if (*p == '}' || *p == ']') {
            if (--depth == 0) return NULL;
        }
    }
    return NULL;
}

double tu_json_number(const char *json, const char *key) {
    const char *p = tu_json_value(json, key);
    if (!p) fail_msg("--stats lacks \"%s\"", key);
    char *end;
    double v = strtod(p, &end);
    if (end == p) fail_msg("--stats \"%s\" is not a number", key);
    return v;
}

int tu_json_bool(const char *json, const char *key) {
    const char *p = tu_json_value(json, key);
    if (!p) fail_msg("--stats lacks \"%s\"", key);
    if (!strncmp(p, "true", 4)) return 1;
    if (!strncmp(p, "false", 5)) return 0;
    fail_msg("--stats \"%s\" is not a boolean", key);
    return -1;
}
