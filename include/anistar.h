/*
 * anistar — anisotropic Delaunay meshes of surfaces.
 *
 * The one public header. Every public symbol starts with anistar_ or ANISTAR_.
 *
 * Conventions (all functions):
 *  - Handles are opaque and come in create/free pairs; free functions accept NULL.
 *  - Fallible functions return an anistar_status (ANISTAR_OK == 0). On failure the
 *    context that the call used keeps a one-line message: anistar_last_error(ctx).
 *  - Nothing is global: every object hangs off a context. A context and the objects
 *    made from it may be used by one thread at a time; two contexts in two threads
 *    never interfere.
 *  - The library never prints, never calls exit or abort, and installs no signal
 *    handlers.
 *  - Symmetric tensors are 6 doubles in the order m11 m12 m13 m22 m23 m33.
 *  - Points are double[3].
 *
 * MIT licence; see LICENSE.
 */
#ifndef ANISTAR_H
#define ANISTAR_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32) && defined(ANISTAR_BUILDING_DLL)
#define ANISTAR_API __declspec(dllexport)
#elif defined(__GNUC__) || defined(__clang__)
#define ANISTAR_API __attribute__((visibility("default")))
#else
#define ANISTAR_API
#endif

/* ------------------------------------------------------------------------------------ */
/* Version                                                                                */
/* ------------------------------------------------------------------------------------ */

#define ANISTAR_VERSION_MAJOR 0
#define ANISTAR_VERSION_MINOR 1
#define ANISTAR_VERSION_PATCH 0
/* Encoded as MAJOR*10000 + MINOR*100 + PATCH: compare with anistar_version_number(). */
#define ANISTAR_VERSION_NUMBER \
    (ANISTAR_VERSION_MAJOR * 10000 + ANISTAR_VERSION_MINOR * 100 + ANISTAR_VERSION_PATCH)

/* The version of the library linked at run time, "MAJOR.MINOR.PATCH". Static string. */
ANISTAR_API const char *anistar_version(void);
/* The same as a number, comparable with ANISTAR_VERSION_NUMBER. */
ANISTAR_API int anistar_version_number(void);

/* ------------------------------------------------------------------------------------ */
/* Status                                                                                 */
/* ------------------------------------------------------------------------------------ */

/* X-macro table: name, value, message. One table feeds the enum and the strings. */
#define ANISTAR_STATUS_TABLE(X)                                                           \
    X(OK, 0, "success")                                                                   \
    X(INCOMPLETE, 1, "stopped at a limit; the mesh of consistent facets is valid")       \
    X(EINVAL, 2, "invalid argument")                                                      \
    X(ENOMEM, 3, "out of memory")                                                         \
    X(EIO, 4, "input/output error")                                                       \
    X(EFORMAT, 5, "malformed or unsupported file or expression")                          \
    X(ENOSURFACE, 6, "no surface found inside the bounding sphere")                       \
    X(ECANCELED, 7, "canceled by the caller")                                             \
    X(EINTERNAL, 8, "internal error (a bug in anistar: please report it)")

typedef enum anistar_status {
#define ANISTAR_STATUS_ENUM_(name, value, msg) ANISTAR_##name = value,
    ANISTAR_STATUS_TABLE(ANISTAR_STATUS_ENUM_)
#undef ANISTAR_STATUS_ENUM_
        ANISTAR_STATUS_COUNT_ /* not a status: the number of statuses */
} anistar_status;

/* A static message for a status, e.g. "out of memory"; "unknown status" otherwise. */
ANISTAR_API const char *anistar_status_string(anistar_status st);
/* The enumerator's name without prefix, e.g. "ENOMEM"; "UNKNOWN" otherwise. */
ANISTAR_API const char *anistar_status_name(anistar_status st);

/* ------------------------------------------------------------------------------------ */
/* Context                                                                                */
/* ------------------------------------------------------------------------------------ */

/*
 * A realloc-style allocator (as Lua's lua_Alloc):
 *   fn(user, NULL, 0, n)       allocate n > 0 bytes, NULL on failure;
 *   fn(user, p, old, n)        resize the block p of old bytes to n > 0 bytes; on failure
 *                              return NULL and leave p untouched;
 *   fn(user, p, old, 0)        free p (p may be NULL); the return value is ignored.
 * Blocks must be aligned for any object type (as malloc's). `old` is always the size
 * the block was last allocated with, so a pool or a counting allocator needs no header.
 */
typedef void *(*anistar_alloc_fn)(void *user, void *ptr, size_t old_size, size_t new_size);

typedef struct anistar_allocator {
    anistar_alloc_fn fn; /* in: required */
    void *user;          /* in: passed to fn, owned by the caller */
} anistar_allocator;

typedef struct anistar_context anistar_context;

/* Create a context. a == NULL uses malloc/realloc/free; otherwise *a is copied and must
 * stay usable until anistar_context_free. Returns NULL when memory runs out. */
ANISTAR_API anistar_context *anistar_context_new(const anistar_allocator *a);
/* Free the context. Every object made from it must have been freed before. NULL is ok. */
ANISTAR_API void anistar_context_free(anistar_context *ctx);
/* The message of the last failed call made with ctx ("" if none). Owned by ctx, valid
 * until the next call that uses ctx. ctx == NULL gives a static message. */
ANISTAR_API const char *anistar_last_error(const anistar_context *ctx);
/* The status of the last failed call made with ctx (ANISTAR_OK if none). */
ANISTAR_API anistar_status anistar_last_status(const anistar_context *ctx);

/* ------------------------------------------------------------------------------------ */
/* Exact geometric predicates                                                             */
/* ------------------------------------------------------------------------------------ */

/*
 * Adaptive exact predicates (Shewchuk's conventions). The sign is always exact; the
 * magnitude is an approximation of the determinant.
 *
 * anistar_orient3d(a,b,c,d) > 0 when d lies below the plane through a, b, c, where
 *   "below" is the side from which a, b, c appear clockwise; equivalently a, b, c appear
 *   counterclockwise seen from above. It is the determinant
 *   | a-d ; b-d ; c-d | (rows), 0 when the four points are coplanar.
 * anistar_insphere(a,b,c,d,e) > 0 when e lies inside the sphere through a, b, c, d,
 *   provided orient3d(a,b,c,d) > 0 (the sign flips otherwise); 0 when cospherical.
 *
 * Valid input range: finite coordinates whose nonzero magnitudes lie in
 * [1e-40, 1e+40] (no intermediate product of the exact evaluation underflows or
 * overflows there). NaN or infinite coordinates give a NaN result. Outside the range
 * the sign may be wrong.
 */
ANISTAR_API double anistar_orient3d(const double a[3], const double b[3], const double c[3],
                                    const double d[3]);
ANISTAR_API double anistar_insphere(const double a[3], const double b[3], const double c[3],
                                    const double d[3], const double e[3]);

/* ------------------------------------------------------------------------------------ */
/* Metric tensors                                                                         */
/* ------------------------------------------------------------------------------------ */

/*
 * A metric tensor M is symmetric positive definite, given as m11 m12 m13 m22 m23 m33.
 * These functions return ANISTAR_EINVAL (with a message in ctx) for NULL arguments,
 * non-finite entries, or a tensor that is not positive definite or whose condition
 * number exceeds 1e24.
 */

/* The distortion gamma(M, N) = max(|F_M F_N^-1|, |F_N F_M^-1|) >= 1 between two metrics
 * (F = M^(1/2)); 1 iff M == N (paper 2.2). */
ANISTAR_API anistar_status anistar_tensor_distortion(anistar_context *ctx, const double m[6],
                                                     const double n[6], double *gamma);
/* The M-distance |M^(1/2) (b - a)| between two points. */
ANISTAR_API anistar_status anistar_tensor_distance(anistar_context *ctx, const double m[6],
                                                   const double a[3], const double b[3],
                                                   double *dist);
/* The symmetric square root F = M^(1/2) (F^T F = M), as 6 doubles. */
ANISTAR_API anistar_status anistar_tensor_sqrt(anistar_context *ctx, const double m[6],
                                               double f[6]);

/* ==== SURFACES AND METRIC FIELDS (issue 4) — section owned by the surface layer ==== */
/* ==== END SURFACES AND METRIC FIELDS ==== */

#ifdef __cplusplus
}
#endif

#endif /* ANISTAR_H */
