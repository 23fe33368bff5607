// cgal_del3.cpp — the reference the star-triangulator targets are stated against (issue 3):
// CGAL's Delaunay_triangulation_3 with the Epick kernel, timed on the same point families
// as bench/bench_del3.c: 10^6 uniform points in the unit cube and 10^6 points on a torus
// surface (range construction: CGAL sorts them spatially), and 40-point star triangulations
// built from scratch (8 box corners pushed to general position + 32 points of the patch
// z = (x^2 - 2 y^2)/2 over [-0.1, 0.1]^2), inserted one by one with the last vertex's cell
// as hint, and as a range.
//
// NOT part of the build and not a dependency of anistar (C++, needs CGAL): a measurement
// kept so that docs/benchmarks.md's CGAL numbers can be re-measured on any machine:
//
//   apt-get install -y libcgal-dev
//   g++ -O3 -DNDEBUG -std=c++17 bench/reference/cgal_del3.cpp -o /tmp/cgal_del3 -lgmp -lmpfr
//   /tmp/cgal_del3 [N (default 1000000)] [stars (default 100000)]
//
// Prints CPU time of this process (CLOCK_PROCESS_CPUTIME_ID), as bench_del3 does.
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <vector>

typedef CGAL::Exact_predicates_inexact_constructions_kernel Kernel;
typedef CGAL::Delaunay_triangulation_3<Kernel> Delaunay;
typedef Kernel::Point_3 Point;

namespace {

struct Xorshift {
    unsigned long long s;
    double unit() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        return (double)(s >> 11) * 0x1.0p-53;
    }
};

double cpu_seconds() {
    timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void bulk(const char *name, const std::vector<Point> &pts) {
    double c0 = cpu_seconds();
    Delaunay dt(pts.begin(), pts.end());
    double c1 = cpu_seconds();
    std::printf("| %-24s | %8zu | %7.2f | %10.0f | %6.2f |\n", name, pts.size(), c1 - c0,
                (double)pts.size() / (c1 - c0),
                (double)dt.number_of_finite_cells() / (double)pts.size());
}

} // namespace

int main(int argc, char **argv) {
    int n = argc > 1 ? std::atoi(argv[1]) : 1000000;
    int count = argc > 2 ? std::atoi(argv[2]) : 100000;
    if (n < 1000) n = 1000;
    if (count < 1) count = 1;
    Xorshift rng = {0x1234567ULL};
    std::printf("| %-24s | %8s | %7s | %10s | %6s |\n", "CGAL 3D Delaunay (Epick)", "points",
                "cpu s", "points/s", "tets/p");
    std::printf("|--------------------------|----------|---------|------------|--------|\n");
    std::vector<Point> pts;
    pts.reserve((size_t)n);
    for (int i = 0; i < n; i++) {
        double x = rng.unit(), y = rng.unit(), z = rng.unit();
        pts.push_back(Point(x, y, z));
    }
    bulk("uniform cube", pts);
    pts.clear();
    for (int i = 0; i < n; i++) {
        double a = 6.283185307179586 * rng.unit(), b = 6.283185307179586 * rng.unit();
        pts.push_back(Point((1 + 0.3 * std::cos(b)) * std::cos(a),
                            (1 + 0.3 * std::cos(b)) * std::sin(a), 0.3 * std::sin(b)));
    }
    bulk("torus surface (R/r=3.3)", pts);

    enum { NSETS = 1000, NPTS = 40 };
    std::vector<std::vector<Point>> sets(NSETS);
    for (int t = 0; t < NSETS; t++) {
        for (int c = 0; c < 8; c++) {
            double q[3];
            for (int k = 0; k < 3; k++) {
                double s = (c >> k) & 1 ? 3.0 : -3.0;
                q[k] = s * (1.0 + 0.02 * ((c * 7 + k * 3) % 5) + 0.001 * c);
            }
            sets[t].push_back(Point(q[0], q[1], q[2]));
        }
        for (int i = 8; i < NPTS; i++) {
            double x = 0.2 * rng.unit() - 0.1, y = 0.2 * rng.unit() - 0.1;
            sets[t].push_back(Point(x, y, 0.5 * (x * x - 2 * y * y)));
        }
    }
    size_t cells = 0;
    double c0 = cpu_seconds();
    for (int k = 0; k < count; k++) {
        Delaunay dt;
        Delaunay::Cell_handle hint;
        for (const Point &p : sets[(size_t)k % NSETS]) hint = dt.insert(p, hint)->cell();
        cells += dt.number_of_cells();
    }
    double c1 = cpu_seconds();
    std::printf("\n40-point star from scratch, one by one (hinted): %.2f us per star\n",
                1e6 * (c1 - c0) / count);
    c0 = cpu_seconds();
    for (int k = 0; k < count; k++) {
        const std::vector<Point> &s = sets[(size_t)k % NSETS];
        Delaunay dt(s.begin(), s.end());
        cells += dt.number_of_cells();
    }
    c1 = cpu_seconds();
    std::printf("40-point star from scratch, as a range: %.2f us per star (%.1f cells per star)\n",
                1e6 * (c1 - c0) / count, (double)cells / (2.0 * count));
    return 0;
}
