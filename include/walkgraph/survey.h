// Radio maps learnt from walks (issue 44): `walkgraph survey WALK... --out MAP` and
// `--radio-map MAP`.
//
//   std::vector<walkgraph::Walk> walks = ...;  // walks of one building, with truth
//   auto map = walkgraph::SurveyRadioMap(walks, walkgraph::SurveyOptions());
//   walkgraph::ApplyRadioMap(map->anchors, &other_walk);  // its unsurveyed anchors get priors
//
// Each walk is solved by fg-batch with its truth as position factors (waypoints), its anchors of
// unknown or uncertain position states of the graph (smoothers/step_graph.h); an anchor heard
// in several walks gets the information-weighted mean of their estimates. The map is an
// anchors.csv (io.h ReadAnchorsFile): position and a 1σ that is the fused covariance's largest
// axis, inflated by the walks' disagreement where they disagree beyond their covariances.
// One walk's covariance is that solve's, from a radio model that is not the truth: where
// several walks place the same anchors, the median of their disagreements (the map's variance
// factor, RadioMap::variance_factor, at least 1) measures how far the walks' covariances
// understate their errors, and every anchor's covariance is scaled by it — an anchor that one
// walk placed too, which has no disagreement of its own. On the four shared IPIN trials the
// walks disagree by a factor of 31–2564 (leave one out; σ 6–51× its solve's).
#ifndef WALKGRAPH_SURVEY_H_
#define WALKGRAPH_SURVEY_H_

#include <vector>

#include <Eigen/Core>

#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

struct SurveyOptions {
  // 1σ of a truth sample used as a waypoint (m). Our choice: IPIN's landmarks are marked on a
  // plan to about this (not documented by IPIN); a simulated truth is exact.
  double checkpoint_sigma_m = 0.5;
  // At most one waypoint per this span (s) of truth: a continuous truth (simulator, Vicon) would
  // otherwise add hundreds of factors per minute that fix the path no better.
  double checkpoint_spacing_s = 1.0;
  // Scale every anchor's covariance by the map's variance factor (RadioMap::variance_factor);
  // false: each keeps its own walks' covariance (scaled by its own disagreement only).
  bool pool_disagreement = true;
  Status Validate() const;
};

// One mapped anchor, with what the map's anchors.csv cannot hold.
struct SurveyedAnchor {
  int id = 0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // fused (and inflated), m²
  int walks = 0;                                         // walks whose estimate entered
  int readings = 0;                                      // their readings of it
  // Disagreement of the walks' estimates: Σ (p_w − p)ᵀ C_w⁻¹ (p_w − p) / (2 (walks − 1)); 1 when
  // they agree as their covariances say (0 for one walk). The covariance is scaled by the larger
  // of it and the map's variance factor.
  double disagreement = 0.0;
};

struct RadioMap {
  std::vector<Anchor> anchors;          // the map (anchors.csv)
  std::vector<SurveyedAnchor> details;  // per estimated anchor, in the order of `anchors`
  int unobservable = 0;                 // (walk, anchor) estimates declared unobservable
  // The (upper) median disagreement of the anchors placed by two or more walks, at least 1 (1 when
  // no anchor is: nothing measures it); every placed anchor's covariance is at least this × its
  // fused one (SurveyOptions::pool_disagreement).
  double variance_factor = 1.0;
};

// The map is in the frame of the first walk with surveyed anchors. A walk in a frame of its own
// (a converter's origin per walk: IPIN's) is moved into it by the rigid motion its surveyed
// anchors give (Umeyama; one shared anchor: a shift); surveyed anchors that still disagree by
// more than 0.5 m rms are an error (not one building), and so is a walk with surveyed anchors
// of which none is in that first walk. Walks without surveyed anchors are taken as in the map's
// frame. Errors also: no walk, a walk without truth, fg-batch failing on a walk. Surveyed anchors
// enter the map as the first walk has them; anchors no walk could place are left out.
StatusOr<RadioMap> SurveyRadioMap(const std::vector<Walk>& walks, const SurveyOptions& options);

// The walk's anchors that are not surveyed (unknown or uncertain) and that `map` places: their
// position (x, y) and σ from the map when the map's σ is smaller (a prior, not a constant: the
// graphs keep them states; the filters use the mean), moved into the walk's frame by the rigid
// motion that the anchors surveyed in both give (as SurveyRadioMap; none shared: the same
// frame). Returns how many changed; an error (and the walk unchanged) when those anchors
// disagree by more than 0.5 m rms.
StatusOr<int> ApplyRadioMap(const std::vector<Anchor>& map, Walk* walk);

}  // namespace walkgraph

#endif  // WALKGRAPH_SURVEY_H_
