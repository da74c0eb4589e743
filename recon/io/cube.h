/* cube.h - FITS frame I/O for the seq type (cfitsio at the edge).
 *
 * A sequence on disk is either one FITS cube (NAXIS=3, NAXIS3 = frames),
 * one 2-D image (one frame) or a list of 2-D images / cubes of equal size
 * read as ONE sequence.  Pixels come back as float32 in the seq layout
 * (pixel (x, y) of a frame is frame[y*width + x], x = NAXIS1), with
 * BSCALE/BZERO applied by cfitsio.
 *
 * Streaming: the reader keeps at most one file open and never buffers more
 * than the frame the caller passes in, so 1000 frames of 1024^2 cost the
 * caller's one frame of memory.  The writer grows NAXIS3 with every frame,
 * so after cube_writer_flush() the file on disk is a valid cube of every
 * frame appended so far: a crash loses at most the unflushed frames.
 *
 * Metadata: the standard keywords have fields; every other user keyword
 * travels in a bounded list of extras so a read/write round trip keeps
 * simulation and processing parameters; HISTORY text travels too.
 *
 * The standard header of every image HDU written here (the cube, a 2-D
 * image, each image extension):
 *   DATE      when the file was written (UTC, ISO-8601): the file's, never
 *             copied from a file read;
 *   CREATOR   the program and its version (meta.creator, by default
 *             'specklab ' SPECKLAB_VERSION, base/version.h);
 *   BUNIT     the pixel values' unit when the caller knows it ('adu' for
 *             camera cubes, 'relative flux' for reconstructions);
 *   WCS       derived from the plate scale, never copied (below);
 *   HISTORY   meta.history: the inputs and parameters that made the data,
 *             one entry per line, wrapped over cards of 72 characters;
 *   CHECKSUM, DATASUM  (FITS 4.0 Appendix J) right for the file after
 *             every cube_writer_flush and after close; the streaming cube
 *             keeps its DATASUM as frames are appended (recon/io/datasum.h)
 *             so a flush costs a header's sum, not a read of the data.
 *             Between flushes the header's sums lag the data: a crash
 *             there leaves a cube whose frames read but whose CHECKSUM
 *             fails until it is rewritten (specklabd's salvage does).
 *
 * WCS (FITS Papers I and II).  The pixel grid is seq.h's: +y is north and
 * -x is east (north up, east left), and the centre where reconstructions
 * put the object is pixel (width/2, height/2) 0-based, so CRPIX1 =
 * width/2 + 1 and CRPIX2 = height/2 + 1 (1-based, integer division).
 * With a plate scale s [arcsec/px] (PLTSCALE; rows are pixel_aspect times
 * taller when it is set):
 *   - offsets from the centre, the primary WCS: CTYPE1 'EOFFSET' (towards
 *     the east), CTYPE2 'NOFFSET' (towards the north), linear, CUNIT
 *     'arcsec', CRVAL 0, CDELT1 = -s (east is -x), CDELT2 = +s aspect; a
 *     companion at (dx, dy) px from the primary is at (-dx s, dy s aspect)
 *     arcsec east and north, PA = atan2(east, north);
 *   - when RA and DEC are known as well, the primary WCS is celestial
 *     (RA---TAN, DEC--TAN, CUNIT 'deg', CRVAL = RA, DEC at the centre,
 *     CDELT1 = -s/3600, CDELT2 = s aspect/3600, RADESYS 'ICRS') and the
 *     offsets are the alternate WCS 'A' (CTYPE1A, CDELT1A, ...).
 * Without a plate scale no WCS is written: pixel coordinates only.
 * A read never keeps WCS keywords (the writer derives them for the grid it
 * writes), nor DATE or CREATOR.
 */
#ifndef SL_CUBE_H
#define SL_CUBE_H

#include "base/seq.h"
#include "status.h"

/* ---- metadata ---------------------------------------------------------- */

#define CUBE_KEY_MAX 9      /* 8-character FITS keyword + NUL */
#define CUBE_STR_MAX 69     /* a one-card FITS string value: 68 chars + NUL */
#define CUBE_COMMENT_MAX 73 /* cfitsio's FLEN_COMMENT */
#define CUBE_META_MAX_EXTRA 128
#define CUBE_HISTORY_MAX 8192  /* bytes of HISTORY text in a cube_meta */
#define CUBE_HISTORY_CARD 72   /* text characters on one HISTORY card */

typedef enum cube_kv_type {
    CUBE_KV_NUM,  /* written as an integer when integral, else %.17G */
    CUBE_KV_STR,
    CUBE_KV_BOOL  /* FITS logical; only produced by reading (num = 0/1) */
} cube_kv_type;

typedef struct cube_kv {
    char key[CUBE_KEY_MAX];  /* upper case */
    cube_kv_type type;
    double num;              /* CUBE_KV_NUM, CUBE_KV_BOOL */
    char str[CUBE_STR_MAX];  /* CUBE_KV_STR */
    char comment[CUBE_COMMENT_MAX];
} cube_kv;

typedef struct cube_meta {
    char date_obs[CUBE_STR_MAX];  /* DATE-OBS, ISO-8601 UTC; "" = absent */
    double exptime_s;             /* EXPTIME, NAN = absent */
    char instrume[CUBE_STR_MAX];  /* INSTRUME, "" = absent */
    char object[CUBE_STR_MAX];    /* OBJECT */
    char bunit[CUBE_STR_MAX];     /* BUNIT */
    double plate_scale_arcsec;    /* PLTSCALE [arcsec/pixel], NAN = absent */
    double wavelength_m;          /* WAVELEN [m], NAN = absent */
    double pixel_aspect;          /* PIXASPCT: pixel height / width, NAN =
                                   * square; PLTSCALE is the x pitch */
    double ra_deg, dec_deg;       /* RA, DEC [deg, ICRS] at the image
                                   * centre, NAN = absent; numbers only */
    char creator[CUBE_STR_MAX];   /* CREATOR to write, "" = 'specklab
                                   * <version>'; a read leaves it "" */
    char history[CUBE_HISTORY_MAX]; /* HISTORY entries, each ending '\n' */
    int nextra;
    int ndropped;  /* keywords a read could not keep: list full, or a
                    * value that does not parse (e.g. EXPTIME = 'n/a') */
    cube_kv extra[CUBE_META_MAX_EXTRA];
} cube_meta;

/* Everything absent, no extras. */
void cube_meta_init(cube_meta *m);
/* Add or replace an extra keyword (key is upper-cased).  SL_EINVAL for a
 * key that is empty, longer than 8 characters, not [A-Z0-9_-], structural
 * (NAXIS1, BZERO, CHECKSUM, ...), one the writer derives (DATE, CREATOR,
 * the WCS: CTYPE1, CDELT2A, ...) or one of the standard fields above (set
 * the field instead), or a non-finite number; SL_ERANGE when the list is
 * full or the string is longer than 68 characters.  comment may be NULL;
 * long comments are cut. */
int cube_meta_set_num(cube_meta *m, const char *key, double value,
                      const char *comment);
int cube_meta_set_str(cube_meta *m, const char *key, const char *value,
                      const char *comment);
/* Append one HISTORY entry (printf format).  Written as HISTORY cards of
 * CUBE_HISTORY_CARD characters, wrapped at blanks; a '\n' in the text
 * starts a new card; a character FITS text cannot hold (outside ' '..'~')
 * is written as '?'.  SL_ERANGE when m->history cannot hold it (nothing is
 * added).  A read keeps at most CUBE_HISTORY_MAX / 2 bytes of a file's
 * HISTORY cards, one entry per card, and counts the rest in ndropped, so
 * a caller always has room for its own. */
int cube_meta_add_history(cube_meta *m, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Look up an extra keyword (case-insensitive).  SL_OK, SL_EINVAL when
 * absent, SL_EDATA when it has the other type (a logical reads as a
 * number 0/1).  Standard fields are not extras: read them directly. */
int cube_meta_get_num(const cube_meta *m, const char *key, double *out);
/* *out points into m (valid while m is unchanged). */
int cube_meta_get_str(const cube_meta *m, const char *key, const char **out);

/* ---- reading ----------------------------------------------------------- */

enum {
    /* Return frames containing NaN/Inf as they are instead of failing. */
    CUBE_ALLOW_NONFINITE = 1u << 0
};

typedef struct cube_reader cube_reader;

/* Open a sequence.  npaths == 1: a 2-D image or 3-D cube, from the
 * primary HDU or, when the primary has NAXIS=0, the first image HDU with
 * data; a path containing * ? or [ is a glob(3) pattern whose matches are
 * sorted with strcmp (so f2 sorts after f10 unless numbers are padded).
 * npaths > 1: the files, in order, as one sequence; sizes must agree.
 * Every file's header is read here (to count frames and check sizes), one
 * file at a time; frames are read lazily by cube_reader_next.  Metadata
 * comes from the first file.  A file holding a tile-compressed image
 * (ZIMAGE = T) is refused with SL_EFORMAT, here and by cube_read_ext:
 * cfitsio 4.2 crashes on corrupt ones (recon/io/cube_guard.c); funpack such
 * files first. */
int cube_reader_open(cube_reader **out, const char *const *paths,
                     int npaths, unsigned flags, sl_err *err);
int cube_reader_width(const cube_reader *r);
int cube_reader_height(const cube_reader *r);
int cube_reader_nframes(const cube_reader *r);
const cube_meta *cube_reader_meta(const cube_reader *r);
/* The largest raw value the first file's integer type can hold (BITPIX 8:
 * 255; BITPIX 16 with BZERO 32768: 65535; signed 16: 32767), where an ADC
 * that fills the type saturates; 0 for floating-point data. */
double cube_reader_code_max(const cube_reader *r);
/* Read the next frame into frame[width*height].  SL_OK, SL_EEND after the
 * last frame, or an error (SL_EDATA for NaN/Inf without
 * CUBE_ALLOW_NONFINITE: the message gives the file, the count and the first
 * bad pixel as (x, y, frame), 0-based, frame counted within the file;
 * SL_EFORMAT "truncated" when the file ends before its data).  After
 * SL_EDATA the bad frame is consumed, so a caller may skip it and go on;
 * after any other error the position stays (rewind, or give up). */
int cube_reader_next(cube_reader *r, float *frame);
/* Start again at frame 0 (closes the current file). */
void cube_reader_rewind(cube_reader *r);
/* Go to frame k (0..nframes; nframes: the end) without reading the
 * frames before it: a process reading its own range of a long sequence
 * pays for its frames only.  SL_ERANGE outside. */
int cube_reader_seek(cube_reader *r, int k);
const char *cube_reader_errmsg(const cube_reader *r);
void cube_reader_free(cube_reader *r);
/* A second reader of r's sequence, at frame 0, sharing nothing with r (so
 * each thread may read with its own): the files r scanned, not scanned
 * again.  SL_ENOMEM. */
int cube_reader_dup(cube_reader **out, const cube_reader *r, sl_err *err);

/* Read every frame into a new seq (*out owned by the caller). */
int cube_read(seq **out, cube_meta *meta_or_NULL, const char *const *paths,
              int npaths, unsigned flags, sl_err *err);
/* Read the 2-D image extension named extname (EXTNAME, e.g. "TRUTH") as a
 * one-frame seq.  NaN/Inf is an SL_EDATA error as for frames. */
int cube_read_ext(seq **out, const char *path, const char *extname,
                  sl_err *err);

/* ---- writing ----------------------------------------------------------- */

/* bitpix for cube_writer_open: the FITS values 8 (unsigned byte), 16, 32
 * (signed), -32, -64, and two unsigned conventions (cfitsio's codes):
 * BITPIX 16 with BZERO 32768 for 0..65535 camera data, BITPIX 32 with
 * BZERO 2147483648 for 0..4294967295.  Integer types round half away
 * from zero (cfitsio alone would truncate). */
#define CUBE_BITPIX_U16 20
#define CUBE_BITPIX_U32 40

typedef struct cube_writer cube_writer;

/* Create or overwrite path with an empty cube (NAXIS=3, NAXIS3=0) and its
 * header: DATE-OBS (now, UTC, if meta has none), then EXPTIME, INSTRUME,
 * OBJECT, BUNIT, PLTSCALE, PIXASPCT, WAVELEN, RA, DEC when set, the
 * extras, then the standard header above (DATE, CREATOR, WCS, HISTORY,
 * CHECKSUM, DATASUM).  meta may be NULL.  The path is taken literally (no
 * cfitsio "[ext]" or "!" syntax). */
int cube_writer_open(cube_writer **out, const char *path, int width,
                     int height, int bitpix, const cube_meta *meta,
                     sl_err *err);
/* Append one frame of width*height floats; NAXIS3 then equals the frames
 * written.  For integer bitpix a NaN/Inf or a value outside the type
 * (after rounding) is SL_ERANGE and the frame is NOT written. */
int cube_writer_append(cube_writer *w, const float *frame);
/* Push header and data to the OS: after this the file on disk is a valid
 * cube of every frame appended, its CHECKSUM and DATASUM right (one header
 * rewrite + fill, cheap). */
int cube_writer_flush(cube_writer *w);
/* Append a float32 2-D image extension named extname with meta's keywords
 * and the standard header (meta may be NULL: DATE, CREATOR and the sums).
 * Call it after the last frame: once an extension exists
 * cube_writer_append fails with SL_EINVAL (the cube cannot grow past the
 * extension without rewriting the file). */
int cube_writer_add_image(cube_writer *w, const char *extname,
                          const float *img, int width, int height,
                          const cube_meta *meta_or_NULL);
int cube_writer_nframes(const cube_writer *w);
/* Finalise and close; reports any deferred write error (disk full).  The
 * handle stays valid for errmsg and must still be freed. */
int cube_writer_close(cube_writer *w);
const char *cube_writer_errmsg(const cube_writer *w);
/* Closes if still open (error ignored: call close to see it); NULL ok. */
void cube_writer_free(cube_writer *w);

/* Write s as a float32 file: NAXIS=2 when s->nframes == 1, else NAXIS=3. */
int cube_write(const char *path, const seq *s, const cube_meta *meta,
               sl_err *err);

#endif
