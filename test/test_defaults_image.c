/*
 * test_defaults_image.c — the images of test/data meshed with the defaults (Otsu's
 * threshold, the curvature metric); see test_defaults.c.
 */
#include "defaults_case.h"
#include "test_util.h"

static const dcase cases[] = {
    {"skull_2.9.inr", 1, 0, 0, 1},
    {"brain_t1.mhd", 1, 0, 0, 1},
    {"liver_labels_half.inr", 1, 0, 0, 1},
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
