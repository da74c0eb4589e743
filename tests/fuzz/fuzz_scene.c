/* fuzz_scene.c - libFuzzer target: the scene file parser (scene_read) and,
 * when a file parses, scene_render of what it describes.
 *
 * The input is the file's text, put in a memfd read as /proc/self/fd/N.
 * A scene that parses is rendered on a 32x24 grid twice: at a fixed
 * 0.05 arcsec/pixel (components anywhere, of any size: off-grid points,
 * huge and tiny disks) and at a scale that puts every component inside
 * the grid.  Contract checks abort (a finding): failures carry a negative
 * code and a message; a parsed scene has components with finite position
 * and flux >= 0; the rendered image is non-negative, and finite when the
 * total flux is well inside float range; when everything fits, the image
 * sum does not exceed the total flux.
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "sim/scene.h"
#define FUZZ_NAME "fuzz_scene"
#include "fuzz_util.h"

#define W 32
#define H 24

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void render(const scene *s, double ps, int fits, float *img)
{
    int rc = scene_render(s, img, W, H, ps, 0);
    if (rc != SL_OK) {
        require(rc < 0, "scene_render", "status outside SL_E*");
        return;
    }
    double flux = scene_total_flux(s), sum = 0;
    for (int i = 0; i < W * H; i++) {
        require(img[i] >= 0 || isnan(img[i]), "scene_render",
                "negative pixel");
        require(isfinite(img[i]) || !(flux < 1e30), "scene_render",
                "non-finite pixel from finite fluxes");
        sum += img[i];
    }
    if (fits && flux < 1e30)
        require(sum <= flux * (1 + 1e-4) + 1e-30, "scene_render",
                "image holds more than the total flux");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[64];
    int fd = mem_file(data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    scene *s = NULL;
    sl_err e = {0};
    int rc = scene_read(&s, path, &e);
    close(fd);
    if (rc != SL_OK) {
        require(s == NULL, "scene_read", "scene left on failure");
        check_failure(rc, &e, "scene_read");
        return 0;
    }
    require(scene_ncomp(s) >= 1, "scene_read", "no components");
    for (int i = 0; i < scene_ncomp(s); i++) {
        const scene_comp *c = scene_comp_at(s, i);
        require(isfinite(c->x_arcsec) && isfinite(c->y_arcsec) &&
                    isfinite(c->flux) && c->flux >= 0,
                "scene_read", "component position or flux");
    }
    float *img = malloc(W * H * sizeof *img);
    if (img) {
        render(s, 0.05, 0, img);
        /* Every component edge within H/2 - 2 pixels of the centre. */
        double ps = scene_radius_arcsec(s) / (H / 2 - 2);
        if (isfinite(ps) && ps > 1e-290)
            render(s, ps, 1, img);
        free(img);
    }
    scene_free(s);
    return 0;
}
