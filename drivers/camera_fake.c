/* camera_fake.c - the "fake" camera backend's own part: Aravis's
 * in-process Fake interface, listed and opened, and the source that feeds
 * its fake camera's pixels.  Every other operation is the aravis
 * backend's (camera_aravis.c, camera_aravis_stream.c), so tests on this
 * backend run the production code paths.
 *
 * The Fake interface is off by default in Aravis; enabling it is
 * process-wide and idempotent, so every list and open does it (a
 * process that never asks for the fake never sees it).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera_aravis.h"

int arvcam_fake_list(camera_info **out, int *n, sl_err *err)
{
    arv_enable_interface("Fake");
    arv_update_device_list();
    unsigned count = arv_get_n_devices(), k = 0;
    camera_info *v = calloc(count ? count : 1, sizeof *v);
    if (!v)
        return sl_seterr(err, SL_ENOMEM, "camera list: out of memory");
    for (unsigned i = 0; i < count; i++) {
        const char *proto = arv_get_device_protocol(i);
        if (!proto || strcmp(proto, "Fake") != 0)
            continue;
        snprintf(v[k].id, sizeof v[k].id, "%s", arv_get_device_id(i));
        snprintf(v[k].vendor, sizeof v[k].vendor, "%s", arv_get_device_vendor(i));
        snprintf(v[k].model, sizeof v[k].model, "%s", arv_get_device_model(i));
        snprintf(v[k].serial, sizeof v[k].serial, "%s", arv_get_device_serial_nbr(i));
        snprintf(v[k].address, sizeof v[k].address, "%s", arv_get_device_id(i));
        snprintf(v[k].protocol, sizeof v[k].protocol, "Fake");
        k++;
    }
    if (k == 0) {
        free(v);
        return SL_OK;
    }
    *out = v;
    *n = (int)k;
    return SL_OK;
}

/* Aravis opens whatever answers to the target on any enabled interface:
 * anything but its fake device is refused, so that a test configuration
 * never takes a real camera. */
int arvcam_fake_open(void **st, const char *target, sl_err *err)
{
    arv_enable_interface("Fake");
    return arvcam_open_target(st, target, 1, err);
}

int arvcam_fake_attach(arvcam *a, sl_err *err)
{
    if (!a->fake)
        return SL_OK;
    if (!ARV_IS_FAKE_DEVICE(a->dev))
        return sl_seterr(err, SL_EINVAL, "camera %s: not Aravis's fake camera (the fake "
                         "backend opens only its device, \"Fake_1\")", a->target);
    if (!a->src.attach)
        return SL_OK;
    ArvFakeCamera *fake = arv_fake_device_get_fake_camera(ARV_FAKE_DEVICE(a->dev));
    int rc = a->src.attach(a->src.data, fake, err);
    if (rc != SL_OK && !err->msg[0])
        sl_seterr(err, rc, "camera %s: the source did not attach", a->target);
    return rc;
}

/* Attached at once to the open device, and again by every reconnect. */
int arvcam_set_source(void *st, const camera_source *src, sl_err *err)
{
    arvcam *a = st;
    if (a->acquiring)
        return sl_seterr(err, SL_EINVAL, "camera %s: set the source before starting",
                         a->target);
    camera_source old = a->src;
    a->src = *src;
    int rc = a->cam ? arvcam_fake_attach(a, err) : SL_OK;
    if (rc != SL_OK)
        a->src = old;
    return rc;
}
