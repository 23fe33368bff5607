/*
 * partition.h — internal: the star set split over k parts, simulated in one process
 * (issue 15 item 4; docs/scaling.md says how it maps onto MPI ranks).
 *
 * Each part is a thread standing for a rank, with its own context and star set; the
 * parts meet only at the end of a round, where they exchange sites (the only data a
 * rank would send), so what each part computes depends on the exchanged data alone and
 * the result does not depend on the threads' timing. The surface and the field are
 * shared read-only, as a rank would hold its own copy.
 *
 *  - The split: recursive coordinate bisection of a surface sample (each cut at the
 *    sample's quantile along the longest side of its box), so the parts hold about the
 *    same area. A point belongs to the part whose box holds it (owner).
 *  - Start: every part inserts the run's initial sites (the same in every part: the
 *    sample of the run's start is global and cheap).
 *  - A round: each part refines, inserting only points it owns. A facet's job belongs
 *    to the part owning the facet's surface center (it holds the facet's star, as a
 *    halo copy when the site is across the cut), the topology rule's to the part owning
 *    the star's site; other jobs are dropped, and a job whose point (Pick_valid's)
 *    lies in another part is sent there as a request. Before the first exchange a part
 *    sets aside the jobs whose empty ball leaves its box (it lacks the sites there).
 *  - The exchange, when no part has a job left: each part sends the sites it created
 *    in the round to every part within whose halo they lie, and the requests to their
 *    owners, which drop the stale ones (a site of theirs inside the job's empty ball).
 *    A part's halo: the points within its reach of its box, the reach being how far the
 *    conflict zones of its stars stick out of the box (a site outside a star's zone
 *    leaves it unchanged, paper 5.3). The rounds end when a round creates no site and
 *    no request anywhere.
 *  - The stitch: the union of the owned sites, and of their stars. A facet is in the
 *    stitched mesh when the owned stars of its three vertices hold it (they may be in
 *    three parts). The check: a star set built from the union (one process), its stars
 *    compared with the parts' owned stars, then refined and certified like any run: the
 *    points that run adds are the repairs the seams needed.
 */
#ifndef ANISTAR_PARTITION_H
#define ANISTAR_PARTITION_H

#include <stdint.h>

#include "mesher/mesher.h"

#define AS_PARTITION_MAX 64

typedef struct as_partition_part {
    double lo[3], hi[3];     /* its box (infinite at the outer sides) */
    int64_t owned;           /* sites it owns at the end (initial ones included) */
    int64_t inserted;        /* points it inserted by its own jobs */
    int64_t requests_sent;   /* points of its jobs sent to their owners */
    int64_t deferred;        /* jobs set aside before the first exchange */
    int64_t requests_in;     /* points other parts asked it to insert, inserted */
    int64_t requests_stale;  /* and not inserted: a site of its own lies in their ball */
    int64_t halo_in;         /* other parts' sites it received */
    int64_t sites;           /* sites in its star set at the end (halo included) */
    double cpu_seconds;      /* its thread's CPU time over all rounds */
    double init_seconds;     /* of which its run's start (sample, poles, initial sites) */
    double round_seconds[8]; /* of which its first rounds' (the first without the start) */
    size_t peak_bytes;       /* its context's peak */
} as_partition_part;

typedef struct as_partition_result {
    int k, rounds;
    as_partition_part part[AS_PARTITION_MAX];
    double parallel_seconds; /* sum over the rounds of the slowest part's CPU time */
    double total_seconds;    /* the parts' CPU times summed */
    double wall_seconds;     /* the rounds' wall time in this process */
    int64_t union_sites;     /* the owned sites of all parts */
    int64_t stars_same;      /* owned stars whose restricted facets are those of the same
                                site's star in the star set built from the union */
    int64_t union_facets;    /* distinct restricted facets of the owned stars */
    int64_t union_consistent;/* of them, held by the owned stars of all three vertices */
    int64_t union_inconsistent; /* inconsistent facets of the star set of the union */
    int certified;           /* the run from the union ended certified */
    int64_t final_sites;     /* its vertices */
    int64_t repairs;         /* points it inserted beyond the union */
    double check_seconds;    /* its time */
} as_partition_result;

/*
 * Mesh surf for field with prm split into k parts (1 <= k <= AS_PARTITION_MAX), then
 * stitch and check (see above). *out (may be NULL) receives the checked mesh of the run
 * from the union. Returns OK when that run is certified, INCOMPLETE when it is not (res
 * says how far it got), or an error (a part's or the check's; EINVAL for k).
 */
anistar_status as_partition_run(anistar_context *ctx, const as_surface *surf,
                                const as_field *field, const as_mesher_params *prm, int k,
                                as_partition_result *res, anistar_mesh **out);

#endif /* ANISTAR_PARTITION_H */
