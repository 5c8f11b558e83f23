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
  double centre = 0, sigma = 0;
  int limit_points = 0;  // the points the limits were estimated from (phase I)
  double Ucl() const { return centre + 3 * sigma; }
  double Lcl() const { return centre - 3 * sigma; }
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

// Process capability of a chart's points against a specification (Montgomery, 6th ed., sec. 8.2), sigma the
// chart's within (moving-range) sigma: Cp = (USL - LSL) / 6 sigma, Cpk = min(USL - centre, centre - LSL) / 3 sigma.
// A one-sided specification (no LSL) has no Cp; Cpk = (USL - centre) / 3 sigma. std::nullopt when sigma is 0.
struct Capability {
  std::optional<double> cp;
  double cpk = 0;
};
std::optional<Capability> CapabilityOf(const ControlChart& chart, std::optional<double> lsl, double usl);

}  // namespace topocal::report
