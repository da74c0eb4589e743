/* nbr8.h - the median and the mean of each pixel's up-to-8 neighbours
 * (3x3 less the centre, cut at the image's edges), rawstats' local level
 * and local noise.  By rows: out's rows [y0, y1) from a's w x h, reading
 * a's rows y0 - 1 .. y1, so that bands of rows can go to threads and give
 * the same values as one pass.  Values are finite.
 *
 * The median: a 19-comparator sorting network inside (branch-free, ~4x
 * faster than insertion sort), insertion sort on the border; an even count
 * takes the upper middle.  The mean is summed in double.
 */
#ifndef SL_NBR8_H
#define SL_NBR8_H

void nbr8_median(const float *a, int w, int h, int y0, int y1, float *out);
void nbr8_mean(const float *a, int w, int h, int y0, int y1, float *out);

#endif
