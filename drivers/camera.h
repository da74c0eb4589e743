/* camera.h - machine-vision cameras behind one interface.
 *
 * A backend is a const table of operations (struct camera_backend) chosen
 * by name: "aravis" drives GigE Vision and USB3 Vision cameras through
 * Aravis 0.8; "fake" drives Aravis's in-process fake camera (below: the
 * same code paths as "aravis", no network).  camera.c validates arguments, checks values against the
 * camera's capabilities, remembers settings, counts frames and dispatches;
 * a backend only talks to its library.
 *
 * Handle: camera_open gives an opaque camera; camera_close(NULL) is a
 * no-op.  Every fallible call returns SL_OK or a negative code, the message
 * kept in the handle (camera_errmsg) or, for camera_list / camera_open, in
 * the caller's sl_err.  Messages start with "camera ADDRESS:" and say what
 * to check ("camera 127.0.0.1: no reply ...").  Besides the SL_E* codes
 * there are three driver codes, declared in the camera's range of
 * status.h (sl_strstatus names them): CAMERA_ETIMEOUT (nothing within the
 * deadline: retry), CAMERA_ELOST (control lost: camera_reconnect) and
 * CAMERA_ENODEV (no such camera, or it does not answer).
 *
 * Acquisition: camera_start makes a stream with a pool of N buffers;
 * camera_pop waits up to timeout_ms for the next buffer and copies its
 * pixels into the caller's buffer.  A buffer that arrived damaged (missing
 * packets, timeout, size mismatch, aborted...) is returned with SL_OK and
 * its status, pixels NOT copied, and counted in camera_stats.failed: the
 * caller never mistakes it for a good frame.  Every buffer popped is
 * counted exactly once: completed + failed = buffers returned.
 *
 * Control lost: when the camera stops answering its heartbeat (cable
 * pulled, process killed) the backend flags it, and camera_pop returns
 * CAMERA_ELOST within ~100 ms of the flag (it waits in short slices).
 * Aravis raises the flag about 5 s after the last reply (3 s heartbeat
 * timeout plus retries); until then camera_pop returns CAMERA_ETIMEOUT
 * after each timeout_ms.  camera_reconnect re-opens the same address or id,
 * re-applies every setting made through this interface and restarts the
 * stream if it was running; statistics carry over, the frame-id count
 * included (frames the camera sent meanwhile are id gaps).
 *
 * Threads: one thread per handle.  Not async-signal-safe.
 */
#ifndef SL_CAMERA_H
#define SL_CAMERA_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

#define CAMERA_STR_MAX 128

typedef struct camera_info {
    char id[CAMERA_STR_MAX];       /* backend device id ("Aravis-Fake-GV01") */
    char vendor[CAMERA_STR_MAX];
    char model[CAMERA_STR_MAX];
    char serial[CAMERA_STR_MAX];
    char address[CAMERA_STR_MAX];  /* IPv4 for GigE, bus path for USB3 */
    char protocol[32];             /* "GigEVision", "USB3Vision" */
} camera_info;

/* Pixel formats the interface delivers (Mono10/12 unpacked arrive as
 * 16-bit containers and read as Mono16 would). */
typedef enum camera_pixfmt {
    CAMERA_PIX_UNKNOWN = 0,
    CAMERA_PIX_MONO8 = 1,
    CAMERA_PIX_MONO16 = 2,
    CAMERA_PIX_MONO10 = 3,
    CAMERA_PIX_MONO12 = 4
} camera_pixfmt;
#define CAMERA_PIXF(f) (1u << (f))  /* bit of a format in camera_caps */

typedef enum camera_trigger {
    CAMERA_TRIGGER_FREE_RUN = 0,   /* frames at the frame rate */
    CAMERA_TRIGGER_SOFTWARE = 1,   /* one frame per camera_trigger_software */
    CAMERA_TRIGGER_HARDWARE = 2    /* the first hardware line (Line0/1) */
} camera_trigger;

typedef struct camera_caps {
    int sensor_width, sensor_height;   /* pixels */
    unsigned pixel_formats;            /* CAMERA_PIXF(CAMERA_PIX_*) bits */
    double exposure_min_us, exposure_max_us;
    double gain_min_db, gain_max_db;   /* NAN when the camera has no gain */
    double frame_rate_min_hz, frame_rate_max_hz; /* NAN when not settable */
    int binning_max;                   /* 1 when the camera cannot bin */
    int software_trigger;              /* 1 when supported */
} camera_caps;

typedef struct camera_config {
    int x, y, width, height;    /* ROI in sensor pixels (after binning) */
    int bin_x, bin_y;
    camera_pixfmt pixel_format;
    double exposure_us;
    double gain_db;             /* NAN when the camera has no gain */
    double frame_rate_hz;       /* NAN when not readable */
    camera_trigger trigger;
} camera_config;

typedef enum camera_frame_status {
    CAMERA_FRAME_SUCCESS = 0,
    CAMERA_FRAME_MISSING_PACKETS,  /* packets lost on the link */
    CAMERA_FRAME_TIMEOUT,          /* not all packets before the deadline */
    CAMERA_FRAME_SIZE_MISMATCH,    /* image larger than the buffer */
    CAMERA_FRAME_ABORTED,          /* acquisition stopped mid-frame */
    CAMERA_FRAME_WRONG_PACKET_ID,
    CAMERA_FRAME_CLEARED,
    CAMERA_FRAME_FILLING,
    CAMERA_FRAME_FORMAT,           /* a pixel format this interface lacks */
    CAMERA_FRAME_UNKNOWN,
    CAMERA_FRAME_NSTATUS
} camera_frame_status;

/* One popped buffer.  In: exactly one of u16 / f32 (the caller's pixels)
 * and its capacity in pixels.  Out: everything else.  Pixels (x, y) land
 * at [y*width + x] and are written ONLY when status == SUCCESS. */
typedef struct camera_frame {
    uint16_t *u16;
    float *f32;
    size_t capacity_px;
    int width, height, x, y;
    camera_pixfmt pixel_format;
    uint64_t frame_id;       /* the camera's block id (GigE: 1..65535);
                                0 = unknown (a damaged frame whose leader
                                packet was lost: id and timestamps are
                                then 0) */
    uint64_t cam_ts_ns;      /* camera clock */
    uint64_t sys_ts_ns;      /* host clock (CLOCK_REALTIME) at arrival */
    camera_frame_status status;
} camera_frame;

typedef struct camera_stats {
    uint64_t completed;        /* SUCCESS buffers returned by camera_pop */
    uint64_t failed;           /* non-SUCCESS buffers returned */
    uint64_t by_status[CAMERA_FRAME_NSTATUS]; /* returned, per status */
    uint64_t missing_packets;  /* GigE packets never received */
    uint64_t resent_packets;   /* GigE packets received after a resend */
    uint64_t underruns;        /* frames dropped: no free buffer */
    uint64_t id_gaps;          /* frame ids never returned with that id:
                                  frames wholly lost (all packets, or no
                                  free buffer) plus damaged frames of
                                  unknown id; returned frames with an id +
                                  id_gaps = the span of ids seen */
    uint64_t timeouts;         /* camera_pop calls that returned ETIMEOUT */
    uint64_t reconnects;       /* successful camera_reconnect calls */
} camera_stats;

typedef struct camera camera;

/* The operations a backend provides.  `st` is the backend's own state;
 * errors go to err with a "camera ADDRESS:" prefix.  camera.c has checked
 * the arguments (non-NULL, positive sizes, values within camera_caps, a
 * started stream for pop).  reconnect only re-opens (dropping any
 * stream); camera.c then re-applies the settings and restarts. */
struct camera_source;

typedef struct camera_backend {
    const char *name;
    const char *summary;
    int (*list)(camera_info **out, int *n, sl_err *err);
    int (*open)(void **st, const char *id_or_address, sl_err *err);
    void (*close)(void *st);
    int (*info)(void *st, camera_info *out, sl_err *err);
    int (*caps)(void *st, camera_caps *out, sl_err *err);
    int (*get_config)(void *st, camera_config *out, sl_err *err);
    int (*set_roi)(void *st, int x, int y, int w, int h, sl_err *err);
    int (*set_binning)(void *st, int bx, int by, sl_err *err);
    int (*set_pixel_format)(void *st, camera_pixfmt f, sl_err *err);
    int (*set_exposure_us)(void *st, double us, sl_err *err);
    int (*set_gain_db)(void *st, double db, sl_err *err);
    int (*set_frame_rate_hz)(void *st, double hz, sl_err *err);
    int (*set_trigger)(void *st, camera_trigger mode, sl_err *err);
    int (*trigger_software)(void *st, sl_err *err);
    int (*start)(void *st, int nbuffers, sl_err *err);
    /* SL_OK with out filled (any status), CAMERA_ETIMEOUT, CAMERA_ELOST. */
    int (*pop)(void *st, int timeout_ms, camera_frame *out, sl_err *err);
    int (*stop)(void *st, sl_err *err);
    /* Transport counters only (missing/resent packets, underruns, id
     * gaps); camera.c counts the frames. */
    void (*stats)(void *st, camera_stats *out);
    int (*reconnect)(void *st, int timeout_ms, sl_err *err);
    /* How long the camera keeps this host in control without hearing
     * from it; SL_OK and *ms = 0 when the transport has no heartbeat. */
    int (*set_heartbeat_ms)(void *st, int ms, sl_err *err);
    int (*get_heartbeat_ms)(void *st, int *ms, sl_err *err);
    /* SL_OK while this host controls the camera.  probe 0: from what the
     * transport's keep-alive last saw, no traffic; probe 1: ask the camera
     * (one control round trip). */
    int (*check)(void *st, int probe, sl_err *err);
    /* Where a simulated sensor's pixels come from (camera_set_source);
     * NULL for a backend of real cameras. */
    int (*set_source)(void *st, const struct camera_source *src, sl_err *err);
} camera_backend;

extern const camera_backend camera_backend_aravis;
extern const camera_backend camera_backend_fake;

/* The backend called name ("aravis"); NULL or "" gives the default
 * (aravis).  NULL when unknown. */
const camera_backend *camera_backend_find(const char *name);
/* Backends compiled in, NULL-terminated. */
const camera_backend *const *camera_backends(void);

/* Every camera the backend finds (GigE discovery takes ~1 s).  *out is an
 * array of *n entries to free() (NULL when none). */
int camera_list(const char *backend, camera_info **out, int *n, sl_err *err);

/* Open by device id (as camera_list gives it) or IPv4 address.  An
 * address is contacted directly, not through discovery, so it works
 * whichever interface the camera sits on.  CAMERA_ENODEV when nothing
 * answers (about 2.5 s for an address). */
int camera_open(camera **out, const char *backend, const char *id_or_address,
                sl_err *err);
void camera_close(camera *c);
const char *camera_errmsg(const camera *c);
/* The name used in messages: what camera_open was given. */
const char *camera_target(const camera *c);

int camera_info_get(camera *c, camera_info *out);
int camera_caps_get(camera *c, camera_caps *out);
int camera_config_get(camera *c, camera_config *out);

/* Setters; range errors name the allowed range.  Changing the ROI,
 * binning or pixel format is refused while started. */
int camera_set_roi(camera *c, int x, int y, int width, int height);
int camera_set_binning(camera *c, int bin_x, int bin_y);
int camera_set_pixel_format(camera *c, camera_pixfmt f);
int camera_set_exposure_us(camera *c, double exposure_us);
int camera_set_gain_db(camera *c, double gain_db);
int camera_set_frame_rate_hz(camera *c, double frame_rate_hz);
int camera_set_trigger(camera *c, camera_trigger mode);
int camera_trigger_software(camera *c);

/* The heartbeat timeout (GigE Vision GevHeartbeatTimeout, 100..600000 ms):
 * the camera drops this host's control when it hears nothing from it for
 * that long, and Aravis reports "control lost".  A busy host or camera
 * (reconstruction, other programs) can miss the default 3 s; a longer one
 * also keeps a crashed host's control that much longer, so a restarted
 * one waits for it.  Re-applied by camera_reconnect.  A transport with no
 * heartbeat (USB3 Vision) accepts it and reads 0. */
int camera_set_heartbeat_ms(camera *c, int ms);
int camera_heartbeat_ms(camera *c, int *ms);

/* Does this host still control the camera?  camera_check sends nothing:
 * it reports what the heartbeat last saw (GigE Vision: a camera gone for
 * ~5 s, or one that restarted and names no controller, is CAMERA_ELOST
 * within a heartbeat period, 1 s), so it suits an idle loop.  camera_probe
 * asks the camera (one read of its control privilege; ~2.5 s when it does
 * not answer): a camera restarted since the last heartbeat is CAMERA_ELOST
 * at once, which is what a run's start needs.  SL_OK, CAMERA_ELOST (take
 * it again: camera_reconnect or a new handle), or the read's error.  A
 * transport without a control privilege (USB3 Vision) is SL_OK. */
int camera_check(camera *c);
int camera_probe(camera *c);

/* Start streaming into a pool of nbuffers buffers (2..1024; 0 = 16).  An
 * acquisition the camera may still run (towards a stream this handle no
 * longer has: control lost and taken back) is stopped first, so that the
 * frames come to this stream. */
int camera_start(camera *c, int nbuffers);
/* Next buffer within timeout_ms (>= 0): SL_OK (check out->status),
 * CAMERA_ETIMEOUT, CAMERA_ELOST, SL_ERANGE when a good frame does not fit
 * out->capacity_px (the frame is then counted as failed, SIZE_MISMATCH). */
int camera_pop(camera *c, int timeout_ms, camera_frame *out);
int camera_stop(camera *c);
int camera_is_started(const camera *c);
void camera_stats_get(const camera *c, camera_stats *out);
/* Re-open the same id/address, trying until timeout_ms has passed (plus
 * the one attempt under way, ~2.5 s for an absent GigE camera); settings
 * made through this interface are re-applied and the stream restarted if
 * it was started.  Statistics carry over. */
int camera_reconnect(camera *c, int timeout_ms);

/* ---- the in-process fake camera ("fake" backend) ------------------------
 *
 * Aravis's "Fake" interface serves one camera inside this process (device
 * id "Fake_1"): an ArvFakeDevice whose ArvFakeCamera has GenICam
 * registers (ROI, binning, Mono8/16, exposure, gain, frame rate,
 * triggers) and a stream thread that fills each frame through a
 * fill-pattern callback.  The "fake" backend opens it with the aravis
 * backend's own operations (camera_aravis.c), so settings, streaming,
 * frame accounting and reconnects run the production code; only the
 * transport differs: no GVCP/GVSP, so no fixed UDP port, no network
 * namespace, no packet loss and no heartbeat (camera_check is SL_OK,
 * camera_heartbeat_ms reads 0).  Faults of the link (killed camera,
 * packet loss, a dropped controller) need the GigE mock and stay with the
 * network tests (docs/testing.md).  Each open (and each reconnect) gets a
 * fresh fake camera; the address must name a fake device ("Fake_1"), so
 * a "fake" configuration never drives a real camera.
 *
 * Pixels: without a source, Aravis's own diagonal ramp.  A source sets the
 * fake camera's sensor registers and fill pattern on every (re)connect:
 * attach(data, fake_camera) gets the ArvFakeCamera (void * here: camera.h
 * does not include Aravis) before any setting is re-applied; the fill
 * callback then runs in Aravis's stream thread.  release(data) runs at
 * camera_close.  Tests that link the simulator (mocks/camsrc) attach it
 * directly; a process that must not link a mock (specklabd) loads one
 * from a shared object with camera_load_source: the library exports
 * CAMERA_SOURCE_ENTRY, which parses args (that library's own flags) and
 * fills a camera_source.  The daemon does so only when its configuration
 * names one ([camera] source; the tests' bin/specklab-fake-source.so
 * renders the simulator and polls the fake stage as the GigE mock does). */
typedef struct camera_source {
    int (*attach)(void *data, void *fake_camera, sl_err *err);
    void (*release)(void *data);   /* may be NULL */
    void *data;
} camera_source;

#define CAMERA_SOURCE_ENTRY "specklab_camera_source"
typedef int (*camera_source_entry)(const char *args, camera_source *out, sl_err *err);

/* Attach src now and on every reconnect; a previous source is released.
 * SL_EINVAL on a backend without simulated sensor (a real camera). */
int camera_set_source(camera *c, const camera_source *src);
/* dlopen path, call its CAMERA_SOURCE_ENTRY with args, camera_set_source;
 * the library is closed at camera_close (after release). */
int camera_load_source(camera *c, const char *path, const char *args);

/* Names: "Mono16", "SUCCESS"/"MISSING_PACKETS", "free-run", "timeout"... */
const char *camera_pixfmt_name(camera_pixfmt f);
camera_pixfmt camera_pixfmt_parse(const char *name); /* UNKNOWN if not */
int camera_pixfmt_bytes(camera_pixfmt f);            /* 1 or 2, 0 unknown */
const char *camera_frame_status_name(camera_frame_status s);
const char *camera_trigger_name(camera_trigger t);

#endif
