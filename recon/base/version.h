/* version.h - the one place the version of specklab is written.
 *
 * Every program and every FITS file (CREATOR) takes it from here.  A
 * plain header on purpose: no code, so the build, `--version` and
 * packaging can read it as text.
 */
#ifndef SL_VERSION_H
#define SL_VERSION_H

#define SPECKLAB_VERSION "0.7.0"

#endif
