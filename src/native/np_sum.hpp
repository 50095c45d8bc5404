// numpy's sum of contiguous doubles, to the bit (contact_rhs_window.cpp's window run sums as
// the Python loop does).
#pragma once

namespace packbot_native {

// numpy's sum of n contiguous doubles (its pairwise sum: in order below 8, 8 accumulators
// from 8 to 128, halves above), to the bit.
inline double np_sum(const double *a, int n) {
  if (n < 8) {
    double s = 0.0;
    for (int i = 0; i < n; ++i) s += a[i];
    return s;
  }
  if (n <= 128) {
    double r[8];
    for (int j = 0; j < 8; ++j) r[j] = a[j];
    int i = 8;
    for (; i < n - (n % 8); i += 8)
      for (int j = 0; j < 8; ++j) r[j] += a[i + j];
    double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; ++i) res += a[i];
    return res;
  }
  int n2 = n / 2;
  n2 -= n2 % 8;
  return np_sum(a, n2) + np_sum(a + n2, n - n2);
}

}  // namespace packbot_native
