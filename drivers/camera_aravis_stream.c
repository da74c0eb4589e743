/* camera_aravis_stream.c - the acquisition half of the "aravis" camera
 * backend (camera_aravis.c has the device half): stream and buffer pool,
 * pop with a deadline, frame-id accounting, statistics.
 *
 * Pool: N buffers of PayloadSize bytes pushed at start; each popped
 * buffer is copied to the caller and pushed back at once, so the pool
 * never drains while the caller keeps up.  GigE streams get socket-buffer
 * AUTO: Aravis sets the kernel receive buffer (SO_RCVBUF) to one payload,
 * so a whole large frame fits (with the 208 KiB default, a larger frame
 * loses packets whenever the thread falls behind), but for small frames
 * at high rates the buffer holds only a frame or two: a stream thread
 * starved for longer than that loses whole frames, which show up in
 * id_gaps.  packet-timeout 20 ms and frame-retention 100 ms: a frame with
 * lost packets is given up 100 ms after its last packet, so on a lossy
 * link about 100 ms x frame rate buffers are held by incomplete frames;
 * the pool must exceed that or frames are dropped (underruns).
 */
#include <stdio.h>
#include <string.h>

#include "camera_aravis.h"

/* Fold the stream's counters into the handle's totals and drop it. */
void arvcam_drop_stream(arvcam *a)
{
    if (!a->stream)
        return;
    guint64 done = 0, failures = 0, underruns = 0, resent = 0, missing = 0;
    arv_stream_get_statistics(a->stream, &done, &failures, &underruns);
    if (ARV_IS_GV_STREAM(a->stream))
        arv_gv_stream_get_statistics(ARV_GV_STREAM(a->stream), &resent, &missing);
    a->old_underruns += underruns;
    a->old_resent += resent;
    a->old_missing += missing;
    g_clear_object(&a->stream);
}

int arvcam_start(void *st, int nbuffers, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    guint payload = arv_camera_get_payload(a->cam, &ge);
    if (ge)
        return arvcam_fail(err, a, "read the payload size", ge);
    arv_camera_set_acquisition_mode(a->cam, ARV_ACQUISITION_MODE_CONTINUOUS, NULL);
    /* The camera may still be acquiring towards a stream this handle no
     * longer has (control lost mid-run and taken back: what ran out was
     * the heartbeat, not the acquisition).  AcquisitionStart then changes
     * nothing, and a camera that fixed its destination when it began
     * streaming keeps sending there: Aravis's fake GigE camera, controlled
     * again, starts streaming at its next 100 ms tick to the port it then
     * holds (0, the closed old stream's) and reads the port again only
     * after a stop.  When that tick fell between the reconnect taking
     * control and the new stream's port, no frame ever came
     * (test_daemon_matrix camera_control_lost, 2 runs in 110).  Stopped
     * first, the start below is a real one, towards this stream; a camera
     * that was not acquiring stays stopped (no error to act on). */
    arv_camera_stop_acquisition(a->cam, NULL);
    arvcam_drop_stream(a);
    a->stream = arv_camera_create_stream(a->cam, NULL, NULL, &ge);
    if (!a->stream)
        return arvcam_fail(err, a, "create the stream", ge);
    if (ARV_IS_GV_STREAM(a->stream))
        g_object_set(a->stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO,
                     "packet-timeout", (guint)PACKET_TIMEOUT_US,
                     "frame-retention", (guint)FRAME_RETENTION_US, NULL);
    for (int i = 0; i < nbuffers; i++)
        arv_stream_push_buffer(a->stream, arv_buffer_new_allocate(payload));
    a->payload = payload;
    arv_camera_start_acquisition(a->cam, &ge);
    if (ge) {
        arvcam_drop_stream(a);
        return arvcam_fail(err, a, "start the acquisition", ge);
    }
    a->acquiring = 1;
    /* A new acquisition counts ids afresh; one resumed after a reconnect
     * counts the frames sent meanwhile as gaps. */
    if (!a->resuming)
        a->have_last_id = 0;
    a->resuming = 0;
    return SL_OK;
}

static camera_frame_status from_arv_status(ArvBufferStatus s)
{
    switch (s) {
    case ARV_BUFFER_STATUS_SUCCESS: return CAMERA_FRAME_SUCCESS;
    case ARV_BUFFER_STATUS_MISSING_PACKETS: return CAMERA_FRAME_MISSING_PACKETS;
    case ARV_BUFFER_STATUS_TIMEOUT: return CAMERA_FRAME_TIMEOUT;
    case ARV_BUFFER_STATUS_SIZE_MISMATCH: return CAMERA_FRAME_SIZE_MISMATCH;
    case ARV_BUFFER_STATUS_ABORTED: return CAMERA_FRAME_ABORTED;
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return CAMERA_FRAME_WRONG_PACKET_ID;
    case ARV_BUFFER_STATUS_CLEARED: return CAMERA_FRAME_CLEARED;
    case ARV_BUFFER_STATUS_FILLING: return CAMERA_FRAME_FILLING;
    default: return CAMERA_FRAME_UNKNOWN;
    }
}

/* Signed distance from id a to id b.  GigE Vision 1 block ids cycle
 * through 1..65535 (0 is skipped on wrap), so within that range the
 * distance is taken modulo 65535, forward when under half the cycle;
 * extended (64-bit) ids just count. */
static int64_t id_distance(uint64_t a, uint64_t b)
{
    if (a >= 1 && a <= 65535 && b >= 1 && b <= 65535) {
        int64_t d = ((int64_t)b - (int64_t)a) % 65535;
        d += d < 0 ? 65535 : 0;
        return d > 32767 ? d - 65535 : d;
    }
    return (int64_t)(b - a);
}

/* Frames that never reach a buffer (every packet lost, or no free
 * buffer) show up only as a jump in the id.  Aravis returns frames in
 * completion order, so a damaged frame held until frame-retention can
 * come back after later ones: a jump counts the skipped ids, and a late
 * frame (behind the newest id) takes one back.  Frames of unknown id (0:
 * leader lost) are not tracked, so returned frames with a known id +
 * id_gaps = the span of ids seen, exactly. */
static void track_id(arvcam *a, uint64_t id)
{
    if (!a->have_last_id) {
        a->last_id = id;
        a->have_last_id = 1;
        return;
    }
    int64_t d = id_distance(a->last_id, id);
    if (d > 0) {
        a->id_gaps += (uint64_t)(d - 1);
        a->last_id = id;
    } else if (d < 0 && a->id_gaps > 0) {
        a->id_gaps--;
    }
}

/* Copy a SUCCESS buffer's pixels into the caller's frame; may downgrade
 * the status (format, size).  SL_ERANGE when the caller's buffer is too
 * small. */
static int copy_pixels(arvcam *a, ArvBuffer *b, camera_frame *out, sl_err *err)
{
    ArvBufferPayloadType pt = arv_buffer_get_payload_type(b);
    if (pt != ARV_BUFFER_PAYLOAD_TYPE_IMAGE &&
        pt != ARV_BUFFER_PAYLOAD_TYPE_EXTENDED_CHUNK_DATA) {
        out->status = CAMERA_FRAME_FORMAT;
        return SL_OK;
    }
    out->width = arv_buffer_get_image_width(b);
    out->height = arv_buffer_get_image_height(b);
    out->x = arv_buffer_get_image_x(b);
    out->y = arv_buffer_get_image_y(b);
    out->pixel_format = arvcam_pixfmt(arv_buffer_get_image_pixel_format(b));
    int bpp = camera_pixfmt_bytes(out->pixel_format);
    if (bpp == 0) {
        out->status = CAMERA_FRAME_FORMAT;
        return SL_OK;
    }
    size_t size = 0, npx = (size_t)out->width * (size_t)out->height;
    const unsigned char *p = arv_buffer_get_image_data(b, &size);
    /* Aravis's fake stream fills the whole buffer but leaves its received
     * size 0 (0.8.26): its size is then the payload allocated at start. */
    if (p && size == 0 && ARV_IS_FAKE_DEVICE(a->dev))
        size = a->payload;
    if (!p || size < npx * (size_t)bpp) {
        out->status = CAMERA_FRAME_SIZE_MISMATCH;
        return SL_OK;
    }
    if (npx > out->capacity_px) {
        out->status = CAMERA_FRAME_SIZE_MISMATCH;
        return sl_seterr(err, SL_ERANGE, "camera %s: a %dx%d frame does not fit the "
                         "caller's %zu pixels", a->target, out->width, out->height,
                         out->capacity_px);
    }
    /* GenICam Mono16 (and unpacked Mono10/12) is little-endian. */
    for (size_t i = 0; i < npx; i++) {
        unsigned v = bpp == 1 ? p[i] : (unsigned)p[2 * i] | (unsigned)p[2 * i + 1] << 8;
        if (out->u16)
            out->u16[i] = (uint16_t)v;
        else
            out->f32[i] = (float)v;
    }
    return SL_OK;
}

/* Back to the pool with id and timestamps cleared: Aravis sets them from
 * the GVSP leader only, so a frame whose leader was lost would otherwise
 * carry the id of the buffer's previous frame (seen: ids one pool size
 * old).  Cleared, such a frame reads id 0, "unknown". */
static void recycle(arvcam *a, ArvBuffer *b)
{
    arv_buffer_set_frame_id(b, 0);
    arv_buffer_set_timestamp(b, 0);
    arv_buffer_set_system_timestamp(b, 0);
    arv_stream_push_buffer(a->stream, b);
}

int arvcam_pop(void *st, int timeout_ms, camera_frame *out, sl_err *err)
{
    arvcam *a = st;
    gint64 deadline = g_get_monotonic_time() + (gint64)timeout_ms * 1000;
    ArvBuffer *b = NULL;
    while (!b) {
        if (g_atomic_int_get(&a->lost))
            return arvcam_lost(err, a);
        gint64 left = deadline - g_get_monotonic_time();
        if (left <= 0) {
            b = arv_stream_try_pop_buffer(a->stream);
            if (!b)
                return sl_seterr(err, CAMERA_ETIMEOUT, "camera %s: no frame within %d ms",
                                 a->target, timeout_ms);
        } else {
            b = arv_stream_timeout_pop_buffer(a->stream, (guint64)MIN(left, POP_SLICE_US));
        }
    }
    out->width = out->height = out->x = out->y = 0;
    out->pixel_format = CAMERA_PIX_UNKNOWN;
    out->frame_id = arv_buffer_get_frame_id(b);
    out->cam_ts_ns = arv_buffer_get_timestamp(b);
    out->sys_ts_ns = arv_buffer_get_system_timestamp(b);
    out->status = from_arv_status(arv_buffer_get_status(b));
    if (out->frame_id != 0)
        track_id(a, out->frame_id);
    int rc = SL_OK;
    if (out->status == CAMERA_FRAME_SUCCESS)
        rc = copy_pixels(a, b, out, err);
    recycle(a, b);
    return rc;
}

int arvcam_stop(void *st, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    int rc = SL_OK;
    if (a->cam && !g_atomic_int_get(&a->lost)) {
        arv_camera_stop_acquisition(a->cam, &ge);
        if (ge)
            rc = arvcam_fail(err, a, "stop the acquisition", ge);
    }
    arvcam_drop_stream(a);
    a->acquiring = 0;
    return rc;
}

void arvcam_stats(void *st, camera_stats *out)
{
    arvcam *a = st;
    out->missing_packets = a->old_missing;
    out->resent_packets = a->old_resent;
    out->underruns = a->old_underruns;
    out->id_gaps = a->id_gaps;
    if (a->stream) {
        guint64 done = 0, failures = 0, underruns = 0, resent = 0, missing = 0;
        arv_stream_get_statistics(a->stream, &done, &failures, &underruns);
        if (ARV_IS_GV_STREAM(a->stream))
            arv_gv_stream_get_statistics(ARV_GV_STREAM(a->stream), &resent, &missing);
        out->missing_packets += missing;
        out->resent_packets += resent;
        out->underruns += underruns;
    }
}

