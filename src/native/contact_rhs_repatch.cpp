// ContactRhs: what the native stretch's re-patch (stretch.hpp) changes and puts back: the
// patches of the same shape, a layout of other patch sizes, the loaded patches and plan kept
// and restored.

#include "contact_rhs.hpp"

#include <algorithm>
#include <vector>

// set_patches on raw arrays of the loaded layout's shapes: local (2 h, 4), frame2 (pairs,
// 9), offset0 (pair rows, 2), slide_tol2 (pairs).
void ContactRhs::set_patches_raw(const double *local, const double *frame2, const double *offset0,
                                 const double *slide_tol2) {
  std::copy(local, local + local_.size(), local_.begin());
  std::copy(frame2, frame2 + frame2_.size(), frame2_.begin());
  std::copy(offset0, offset0 + offset0_.size(), offset0_.begin());
  std::copy(slide_tol2, slide_tol2 + slide_tol2_.size(), slide_tol2_.begin());
  lock_mode_ = -1;
  end_valid_ = false;
  jac_valid_ = false;
}

// A re-patch whose patches change size (the same pairs, normals on the same bodies and
// limits: normal_rows.ContactRows._layout's full build): each pair's K (pairs), the new
// points and centres local (2 h, 4), frame2 (pairs, 9), offset0 (pair rows, 2) and
// slide_tol2 (pairs); the body, pair, row and centre indices made from the Ks. As after
// set_layout and set_conditions: no plan, the contact rows' mode.
void ContactRhs::relayout_raw(const std::vector<int> &K, const double *local, const double *frame2,
                              const double *offset0, const double *slide_tol2) {
  const int np = np_, h = h_;
  std::vector<int64_t> b1(np), b2(np);
  for (int p = 0; p < np; ++p) {
    const int64_t first = centre_[p] - pK_[p];  // (the pair's first point)
    b1[p] = body_[first];
    b2[p] = body_[h + first];
  }
  std::vector<int64_t> body2;
  body_.clear();
  pair_.clear();
  rows_.clear();
  centre_.clear();
  int64_t k = 0;
  for (int p = 0; p < np; ++p) {
    for (int j = 0; j <= K[p]; ++j) {
      body_.push_back(b1[p]);
      body2.push_back(b2[p]);
      pair_.push_back(p);
    }
    for (int j = 0; j < K[p]; ++j) rows_.push_back(k + j);
    centre_.push_back(k + K[p]);
    k += K[p] + 1;
  }
  body_.insert(body_.end(), body2.begin(), body2.end());
  local_.assign(local, local + 8 * k);
  frame2_.assign(frame2, frame2 + 9 * np);
  layout_changed();
  offset0_.assign(offset0, offset0 + 2 * mp_);
  slide_tol2_.assign(slide_tol2, slide_tol2 + np_);
  conditions_set_ = true;
  relaid_ = true;
}

// The loaded patches and plan, kept (keep_loaded) and put back (restore_loaded): a
// re-patch that hands back leaves the extension as the caller loaded it.
void ContactRhs::keep_loaded() {
  relaid_ = false;
  kept_body_ = body_;
  kept_pair_ = pair_;
  kept_rows_ = rows_;
  kept_centre_ = centre_;
  kept_local_ = local_;
  kept_frame2_ = frame2_;
  kept_offset0_ = offset0_;
  kept_slide_tol2_ = slide_tol2_;
  kept_engaged_ = engaged_;
  kept_row_slip_ = row_slip_;
  kept_sticks_ = sticks_;
  kept_slip_dir_ = slip_dir_;
  kept_plan_ = {mu_, stick_speed_, baumgarte_};
}

void ContactRhs::restore_loaded() {
  if (relaid_) {
    relaid_ = false;
    body_ = kept_body_;  // (a relayout: the layout's shapes back too)
    pair_ = kept_pair_;
    rows_ = kept_rows_;
    centre_ = kept_centre_;
    local_ = kept_local_;
    frame2_ = kept_frame2_;
    layout_changed();
    offset0_ = kept_offset0_;
    slide_tol2_ = kept_slide_tol2_;
    conditions_set_ = true;
  } else {
    set_patches_raw(kept_local_.data(), kept_frame2_.data(), kept_offset0_.data(),
                    kept_slide_tol2_.data());
  }
  engaged_ = kept_engaged_;
  row_slip_ = kept_row_slip_;
  sticks_ = kept_sticks_;
  slip_dir_ = kept_slip_dir_;
  mu_ = kept_plan_[0];
  stick_speed_ = kept_plan_[1];
  baumgarte_ = kept_plan_[2];
  set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
}
