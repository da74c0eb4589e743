/* utcdate.c - see utcdate.h. */
#include "utcdate.h"

#include <stdio.h>
#include <string.h>

/* Days from 1970-01-01 to year-month-day in the proleptic Gregorian
 * calendar (the era arithmetic of H. Hinnant's days_from_civil). */
static long days_from_civil(long y, int m, int d)
{
    y -= m <= 2;
    long era = (y >= 0 ? y : y - 399) / 400;
    long yoe = y - era * 400;
    long doy = (153L * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
    long doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + doe - 719468;
}

static int days_in_month(long y, int m)
{
    static const int n[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    int leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    return m == 2 && leap ? 29 : n[m - 1];
}

int utcdate_mjd(const char *iso, double *mjd, sl_err *err)
{
    int y = 0, mo = 0, d = 0, hh = 0, mm = 0, used = 0;
    double ss = 0;
    if (!iso || sscanf(iso, "%4d-%2d-%2d%n", &y, &mo, &d, &used) != 3 || used != 10)
        return sl_seterr(err, SL_EINVAL, "date '%s' is not YYYY-MM-DD[Thh:mm:ss]",
                         iso ? iso : "(none)");
    const char *t = iso + used;
    int more = 0;
    if (*t == 'T' && (sscanf(t + 1, "%2d:%2d:%lf%n", &hh, &mm, &ss, &more) != 3 ||
                      t[1 + more] != '\0'))
        return sl_seterr(err, SL_EINVAL, "date '%s': the time is not hh:mm:ss", iso);
    if (*t != 'T' && *t != '\0')
        return sl_seterr(err, SL_EINVAL, "date '%s' is not YYYY-MM-DD[Thh:mm:ss]", iso);
    if (mo < 1 || mo > 12 || d < 1 || d > days_in_month(y, mo) || hh < 0 || hh > 23 ||
        mm < 0 || mm > 59 || !(ss >= 0 && ss < 61))
        return sl_seterr(err, SL_EINVAL, "date '%s' has a field out of range", iso);
    /* 1970-01-01 is MJD 40587 */
    *mjd = (double)(days_from_civil(y, mo, d) + 40587) + (hh + (mm + ss / 60.0) / 60.0) / 24.0;
    return SL_OK;
}

double utcdate_besselian_year(double mjd)
{
    return 1900.0 + (mjd + 2400000.5 - 2415020.31352) / 365.242198781;
}
