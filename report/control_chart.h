#pragma once
// Shewhart individuals chart with the Western Electric run rules, for the fleet view (docs/fleet.md).
//
// Limits from the data (phase I): centre = mean of the series; sigma = mean moving range / d2, d2 = 1.128 for
// ranges of two consecutive points (Montgomery, Introduction to Statistical Quality Control, 6th ed., sec. 6.4).
// The moving range sees point-to-point scatter, not a slow drift, so a drifting series keeps tight limits and the run
// rules catch the drift; a standard deviation of the whole series would widen with the drift and hide it.
//
// Western Electric rules (Western Electric Statistical Quality Control Handbook, 1956), zones in units of sigma
// about the centre; a rule flags the point that completes its pattern:
//   1  one point beyond 3 sigma
//   2  two of three consecutive points beyond 2 sigma on the same side
//   3  four of five consecutive points beyond 1 sigma on the same side
//   4  eight consecutive points on the same side of the centre
// The same rules judge a chart of subgroup means (SubgroupMeansChart), the one a line of thousands of units is
// drawn as: each point's z-score is taken against its own subgroup's sigma / sqrt(n).
//
// Together their in-control average run length is about 92 points (Champ & Woodall 1987): on a stable series of
// 50 points a false alarm is not rare. The fleet report lists each signal with its rule so that the reader can
// weigh it.
#include <optional>
#include <string>
#include <vector>

namespace topocal::report {

inline constexpr double kMovingRangeD2 = 1.128;
inline constexpr int kMinControlChartPoints = 8;  // fewer: no limits (a chart of a handful of units says nothing)

struct ControlSignal {
  int index = 0;  // the point that completes the pattern
  int rule = 0;   // 1..4 as above
};

struct ControlChart {
  double centre = 0, sigma = 0;  // sigma: of one unit (the process's within sigma), what capability is judged by
  int limit_points = 0;  // the units the limits were estimated from (phase I)
  int subgroup_size = 1;  // units per point: 1 for an individuals chart; the control limits are of a point's mean
  double PointSigma() const;  // sigma / sqrt(subgroup_size)
  double Ucl() const { return centre + 3 * PointSigma(); }
  double Lcl() const { return centre - 3 * PointSigma(); }
  std::vector<ControlSignal> signals;  // by index, then rule
  std::vector<bool> flagged;           // per point: some rule flags it
};

// One-line description of a rule, for the report.
std::string WesternElectricRuleText(int rule);

// The chart of `values` (in order of time). The limits (phase I) come from the points with `in_limits` true (all
// when it is empty): the fleet leaves out units that failed their acceptance limits, so that a broken unit does not
// widen the limits every other unit is judged by; the moving ranges are those of consecutive included points. Every
// point is then checked against those limits. std::nullopt when fewer than kMinControlChartPoints points are
// included, or a value is not finite. sigma 0 (every moving range 0) gives a chart with no signals.
std::optional<ControlChart> IndividualsChart(const std::vector<double>& values, const std::vector<bool>& in_limits = {});

// A subgroup of consecutive units: the mean of all of them (what is drawn when none is included) and, by Welford's
// running sums, the count, mean and sum of squared deviations of the included (passing) ones.
struct Subgroup {
  int n = 0;
  double mean = 0;
  int n_in = 0;
  double mean_in = 0, m2_in = 0;
  void Add(double value, bool included);
  // This subgroup followed by `next`, as one (Chan, Golub & LeVeque's pairwise update: exact up to rounding).
  void Merge(const Subgroup& next);
  // The point drawn: the mean of the included units, or of all when none is included.
  double Point() const { return n_in > 0 ? mean_in : mean; }
};

// Shewhart X-bar chart of subgroup means with limits from the data (phase I; Montgomery, 6th ed., sec. 6.3, the
// pooled standard deviation for subgroups of different sizes): centre = mean of the included units; sigma (of one
// unit) = sqrt(sum of the included units' squared deviations from their subgroup means / sum (n_in - 1)), the spread
// within subgroups, which a slow drift between subgroups does not widen; each point is judged against
// centre +- 3 sigma / sqrt(n) of its own size n (the last subgroup may be smaller), by the rules above. The chart's
// subgroup_size is the largest n. std::nullopt when fewer than kMinControlChartPoints subgroups include a unit, no
// subgroup includes two, or a value is not finite. (With about 100 or more degrees of freedom the pooled s needs
// no c4 correction: c4 > 0.997.)
std::optional<ControlChart> SubgroupMeansChart(const std::vector<Subgroup>& groups);

// Process capability of a chart's points against a specification (Montgomery, 6th ed., sec. 8.2), sigma the
// chart's within (moving-range) sigma: Cp = (USL - LSL) / 6 sigma, Cpk = min(USL - centre, centre - LSL) / 3 sigma.
// A one-sided specification (no LSL) has no Cp; Cpk = (USL - centre) / 3 sigma. std::nullopt when sigma is 0.
struct Capability {
  std::optional<double> cp;
  double cpk = 0;
};
std::optional<Capability> CapabilityOf(const ControlChart& chart, std::optional<double> lsl, double usl);

}  // namespace topocal::report
