/* config.h - specklabd's configuration: a GKeyFile read over embedded
 * defaults that point at the mocks (bin/specklab-fake-stage on
 * 127.0.0.1:1502, bin/specklab-fake-camera on 127.0.0.1) with data,
 * catalogue and socket under ./var/.
 *
 * Groups and keys (daemon/specklabd.conf.example documents each):
 *   [camera]  backend address exposure_us pixel_format frame_rate_hz roi
 *             buffers plate_scale_arcsec wavelength_nm lost_timeout_s
 *             max_failed_frames gain_e_per_adu read_noise_e
 *             heartbeat_timeout_ms source source_args
 *   [stage]   backend address unit device baud parity move_timeout_ms
 *             settle_ms response_timeout_ms call_timeout_ms
 *   [screens] SLOT=NAME ...        (the phase-screen wheel)
 *   [masks]   SLOT=NAME[:FILE] ... (built-in "full"/"nrm17", or a mask file)
 *   [paths]   data_dir catalog
 *   [daemon]  socket reconstruct projections tsm_phases skips fftw max_clients
 *             client_idle_timeout_ms catalog_busy_timeout_ms
 *   [calibration] dark flat flat_dark badpix catalogued
 *   [web]     listen allow_remote max_connections (webconf.h)
 * A key the file omits keeps its default; [screens] and [masks] in the
 * file replace the default lists as a whole.  Unknown keys are errors (a
 * typo must not silently fall back to a default).  Relative paths are
 * resolved against the working directory at start; an empty catalog or
 * socket means DATA_DIR/specklab.db and DATA_DIR/specklabd.sock.
 */
#ifndef SL_DAEMON_CONFIG_H
#define SL_DAEMON_CONFIG_H

#include "status.h"

#define CONFIG_MAX_SLOTS 16

typedef struct config_slot {
    int slot;
    char *name;
    char *file;         /* masks: a mask file (mask_read), NULL: built-in */
} config_slot;

typedef struct config {
    /* [camera] */
    char *camera_backend, *camera_address, *pixel_format;
    /* The fake backend's pixel source: a shared object (drivers/camera.h,
     * camera_load_source) and its arguments; NULL: Aravis's own pattern.
     * Tests only: the daemon links no mock and loads nothing unless told. */
    char *camera_source, *camera_source_args;
    double exposure_us;         /* default for start-run */
    double frame_rate_hz;       /* NaN: leave the camera's */
    int roi[4];                 /* x, y, w, h; w == 0: the whole sensor */
    int buffers;
    double plate_scale_arcsec;  /* PLTSCALE of acquired cubes */
    double wavelength_m;        /* WAVELEN */
    double lost_timeout_s;      /* no frame for this long: camera lost */
    int heartbeat_timeout_ms;   /* GevHeartbeatTimeout set on the camera */
    int max_failed_frames;      /* damaged frames before a run fails;
                                 * <= 0: max(100, frames requested) */
    /* The detector's photon statistics, written as GAIN [e-/ADU, scaled
     * by the camera's Gain setting] and RDNOISE [e-] into every cube so
     * that the reconstruction removes the photon bias exactly
     * (recon/pipeline/pipeline.h).  NaN: unknown, keywords not written. */
    double gain_e_per_adu;      /* at camera Gain 0 dB */
    double read_noise_e;
    /* [stage] */
    char *stage_backend, *stage_host, *stage_device;
    int stage_port, stage_unit, stage_baud;
    char stage_parity;          /* rtu: 'N', 'E' (default) or 'O' */
    int move_timeout_ms, settle_ms, response_timeout_ms, call_timeout_ms;
    /* [screens], [masks], sorted by slot */
    config_slot screens[CONFIG_MAX_SLOTS];
    int nscreens;
    config_slot masks[CONFIG_MAX_SLOTS];
    int nmasks;
    /* [paths], [daemon]; absolute after config_load */
    char *data_dir, *catalog, *socket;
    char *reconstruct;          /* "auto", "direct", "tsm", "tsm-fourier", "none" */
    int projections;            /* TSM angles; 0: the pipeline's default */
    int skips;                  /* pipeline_opts.skips (PIPE_SKIP_* bits) */
    int tsm_corrected_phases;   /* 1: pipeline_opts.tsm_corrected_phases
                                 * (effective when cubes carry GAIN) */
    int fftw_measure;           /* 1: FFTW_MEASURE with DATA_DIR/fftw-wisdom */
    int max_clients;
    int client_idle_timeout_ms; /* a connection with nothing in hand this
                                 * long is closed (server.h) */
    int catalog_busy_timeout_ms; /* a write waits this long for another
                                  * process's lock, then fails "locked" */
    /* [calibration]: files applied to every reconstruction (absolute,
     * existing at load; NULL: none), and whether the catalogue's dark and
     * flat runs stand in for an absent file (worker.c says which run). */
    char *calib_dark, *calib_flat, *calib_flat_dark, *calib_badpix;
    int calib_catalogued;
    /* [web] (webconf.h): the page's listener; web_host NULL: no page. */
    char *web_host;             /* numeric, without brackets */
    int web_port;               /* 0: any free port */
    int web_loopback;           /* web_host is a loopback address */
    int web_allow_remote;       /* a non-loopback host was allowed */
    int web_max_connections;
} config;

/* The embedded defaults, as GKeyFile text (also printed by
 * `specklabd --print-defaults`). */
const char *config_defaults_text(void);

/* Load defaults, then path (NULL: none), then the overrides (NULL: keep)
 * and validate.  SL_EINVAL / SL_EIO with a message naming the file and
 * key.  Free with config_clear. */
int config_load(config *c, const char *path, const char *socket_override,
                const char *data_dir_override, sl_err *err);
void config_clear(config *c);

/* The slot entry whose name is name, or whose slot number is the decimal
 * text; NULL when none. */
const config_slot *config_screen_find(const config *c, const char *name_or_slot);
const config_slot *config_mask_find(const config *c, const char *name_or_slot);
const config_slot *config_screen_at(const config *c, int slot);
const config_slot *config_mask_at(const config *c, int slot);

/* "auto", "direct", "tsm", "tsm-fourier" or "none". */
int config_method_valid(const char *name);

#endif
