/* entry.c - bin/specklab-fake-source.so: the speckle simulator
 * (mocks/camsrc/fakesrc.h) as a shared object that a process driving the
 * "fake" camera backend loads with camera_load_source (drivers/camera.h).
 * specklabd does so when its configuration says [camera] source = this
 * file; its args are [camera] source_args.  Tests only: never installed.
 *
 * Built from position-independent copies of camsrc, recon's simulator
 * and common/ (Makefile, FAKESRC_*), linked -Bsymbolic so that its own
 * definitions never bind to a host's symbols of the same name; only the
 * entry point is exported.
 */
#include "fakesrc.h"

__attribute__((visibility("default")))
int specklab_camera_source(const char *args, camera_source *out, sl_err *err);

int specklab_camera_source(const char *args, camera_source *out, sl_err *err)
{
    return fakesrc_new(out, args, err);
}
