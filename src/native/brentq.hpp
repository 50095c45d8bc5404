// SciPy's brentq (Zeros/brentq.c), as packbot.ode.brentq ports it, in its order of operations
// (contact_rhs_events.cpp's row_root locates a row's event with it).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace packbot_native {

// A root of f on [xa, xb] to xtol (and 4 eps relative), within 100 iterations: the root, or NaN
// when none was found; `failed` (set by f) stops the iterations.
template <class F>
double brentq(F &&f, double xa, double xb, double xtol, const bool &failed) {
  const double rtol = 4.0 * 2.220446049250313e-16;
  double xpre = xa, xcur = xb, xblk = 0.0, fblk = 0.0, spre = 0.0, scur = 0.0;
  double fpre = f(xpre), fcur = f(xcur);
  double root = std::numeric_limits<double>::quiet_NaN();
  if (fpre == 0.0) {
    root = xpre;
  } else if (fcur == 0.0) {
    root = xcur;
  } else {
    for (int it = 0; it < 100 && !failed; ++it) {
      if (fpre != 0.0 && fcur != 0.0 && std::copysign(1.0, fpre) != std::copysign(1.0, fcur)) {
        xblk = xpre;
        fblk = fpre;
        spre = scur = xcur - xpre;
      }
      if (std::abs(fblk) < std::abs(fcur)) {
        xpre = xcur;
        xcur = xblk;
        xblk = xpre;
        fpre = fcur;
        fcur = fblk;
        fblk = fpre;
      }
      const double delta = (xtol + rtol * std::abs(xcur)) / 2.0;
      const double sbis = (xblk - xcur) / 2.0;
      if (fcur == 0.0 || std::abs(sbis) < delta) {
        root = xcur;
        break;
      }
      if (std::abs(spre) > delta && std::abs(fcur) < std::abs(fpre)) {
        double stry;
        if (xpre == xblk) {
          stry = -fcur * (xcur - xpre) / (fcur - fpre);
        } else {
          const double dpre = (fpre - fcur) / (xpre - xcur);
          const double dblk = (fblk - fcur) / (xblk - xcur);
          stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre));
        }
        if (2.0 * std::abs(stry) < std::min(std::abs(spre), 3.0 * std::abs(sbis) - delta)) {
          spre = scur;
          scur = stry;
        } else {
          spre = scur = sbis;
        }
      } else {
        spre = scur = sbis;
      }
      xpre = xcur;
      fpre = fcur;
      if (std::abs(scur) > delta)
        xcur += scur;
      else
        xcur += sbis > 0.0 ? delta : -delta;
      fcur = f(xcur);
    }
  }
  return root;
}

}  // namespace packbot_native
