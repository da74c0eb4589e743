-- 004_r0_error.sql - an r0 measurement's 1-sigma error, in metres at the
-- measurement's wavelength (NULL: not stated, as for every row before).
-- Image motion from one run of 100 frames scatters by ~17 % in r0: a
-- figure without its error would read as better than it is.

ALTER TABLE screen_r0 ADD COLUMN r0_err_m REAL
    CONSTRAINT r0_err_nonnegative CHECK (r0_err_m IS NULL OR r0_err_m >= 0);

PRAGMA user_version = 4;
