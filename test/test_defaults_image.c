/*
 * test_defaults_image.c — the images of test/data meshed with the defaults (Otsu's
 * threshold, the curvature metric); see test_defaults.c.
 */
#include "defaults_case.h"
#include "test_util.h"

static const dcase cases[] = {
    {"skull_2.9.inr", 1, 0, 0, 1},
    {"brain_t1.mhd", 1, 0, 0, 1},
    /* a label image: the smoothing fit (bspline.h) makes one closed surface of the labels
     * above Otsu's threshold (127 and 255; their voxels are one 6-connected component;
     * the interpolating fit's ringing at the label jumps made 45 to 74 components) */
    {"liver_labels_half.inr", 1, 2, 1, 1},
};

static void test_defaults_images(void **state) {
    (void)state;
    assert_true(dc_run_all(cases, sizeof cases / sizeof cases[0]));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults_images),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
