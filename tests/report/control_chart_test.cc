// Shewhart individuals chart and the Western Electric rules (report/control_chart.h).
#include "report/control_chart.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace topocal::report {
namespace {

bool HasRule(const ControlChart& c, int rule) {
  for (const auto& s : c.signals) {
    if (s.rule == rule) return true;
  }
  return false;
}

TEST(ControlChart, LimitsFromTheMovingRangeByHand) {
  // Moving ranges 1, 1, 1, 1, 1, 1, 1: mean 1, sigma = 1 / 1.128; centre = mean of 0,1,0,1,... = 0.5.
  const std::vector<double> v = {0, 1, 0, 1, 0, 1, 0, 1};
  const auto c = IndividualsChart(v);
  ASSERT_TRUE(c.has_value());
  EXPECT_DOUBLE_EQ(c->centre, 0.5);
  EXPECT_DOUBLE_EQ(c->sigma, 1.0 / 1.128);
  EXPECT_DOUBLE_EQ(c->Ucl(), 0.5 + 3.0 / 1.128);
  EXPECT_TRUE(c->signals.empty());
  EXPECT_FALSE(IndividualsChart({1, 2, 3}).has_value());  // too few points
}

// Phase I: a broken unit (a FAIL) is charted and flagged, but does not set the limits. The same series with the
// outlier included widens sigma from 1 / 1.128 to 1.9 / 1.128 and hides it (z 2.97: no rule-1 signal; 6.2 without).
TEST(ControlChart, LimitsComeFromTheIncludedPointsOnly) {
  const std::vector<double> v = {0, 1, 0, 1, 0, 1, 0, 1, 6, 0, 1};
  std::vector<bool> in_limits(v.size(), true);
  in_limits[8] = false;
  const auto c = IndividualsChart(v, in_limits);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->limit_points, 10);
  EXPECT_DOUBLE_EQ(c->centre, 0.5);
  EXPECT_DOUBLE_EQ(c->sigma, 1.0 / 1.128);  // moving ranges of consecutive included points: all 1
  EXPECT_TRUE(c->flagged[8]);
  const auto all = IndividualsChart(v);
  ASSERT_TRUE(all.has_value());
  EXPECT_EQ(all->limit_points, 11);
  EXPECT_DOUBLE_EQ(all->sigma, 1.9 / 1.128);
  EXPECT_FALSE(HasRule(*all, 1));
  EXPECT_TRUE(HasRule(*c, 1));
  // Too few included points: no chart.
  std::vector<bool> few(v.size(), false);
  for (int i = 0; i < 7; ++i) few[static_cast<size_t>(i)] = true;
  EXPECT_FALSE(IndividualsChart(v, few).has_value());
  // Values whose sums overflow (1e308 beside 0.1): no limits, rather than an infinite sigma.
  EXPECT_FALSE(IndividualsChart({0.1, 1e308, 0.1, -1e308, 0.1, 1e308, 0.1, 0.1}).has_value());
}

TEST(ControlChart, CapabilityByHand) {
  // centre 0.5, sigma 1 / 1.128: against +-4, Cp = 8 / (6 sigma), Cpk = (4 - 0.5) / (3 sigma).
  const auto c = IndividualsChart({0, 1, 0, 1, 0, 1, 0, 1});
  ASSERT_TRUE(c.has_value());
  const double sigma = 1.0 / 1.128;
  const auto two = CapabilityOf(*c, -4.0, 4.0);
  ASSERT_TRUE(two.has_value());
  ASSERT_TRUE(two->cp.has_value());
  EXPECT_DOUBLE_EQ(*two->cp, 8.0 / (6 * sigma));
  EXPECT_DOUBLE_EQ(two->cpk, 3.5 / (3 * sigma));
  const auto one = CapabilityOf(*c, std::nullopt, 4.0);  // one-sided: no Cp
  ASSERT_TRUE(one.has_value());
  EXPECT_FALSE(one->cp.has_value());
  EXPECT_DOUBLE_EQ(one->cpk, 3.5 / (3 * sigma));
  const auto flat = IndividualsChart({1, 1, 1, 1, 1, 1, 1, 1});
  ASSERT_TRUE(flat.has_value());
  EXPECT_FALSE(CapabilityOf(*flat, -4.0, 4.0).has_value());  // sigma 0: no capability stated
}

TEST(ControlChart, EachRuleFiresOnItsPattern) {
  // A zig-zag of +-1 about 0 (sigma = 2 / 1.128 = 1.77) with one pattern added each time.
  std::vector<double> base;
  for (int i = 0; i < 30; ++i) base.push_back(i % 2 ? 1.0 : -1.0);
  ASSERT_TRUE(IndividualsChart(base)->signals.empty());
  auto with = [&](std::vector<std::pair<int, double>> points) {
    auto v = base;
    for (auto [i, x] : points) v[i] = x;
    return *IndividualsChart(v);
  };
  EXPECT_TRUE(HasRule(with({{15, 12.0}}), 1));  // far beyond 3 sigma
  // Two of three beyond 2 sigma (~3.5 + centre shift) on one side, none beyond 3 sigma.
  EXPECT_TRUE(HasRule(with({{15, 4.4}, {16, 4.4}}), 2));
  // Eight on one side: a run of small positive values.
  std::vector<std::pair<int, double>> run;
  for (int i = 10; i < 18; ++i) run.push_back({i, 0.5});
  const auto r4 = with(run);
  EXPECT_TRUE(HasRule(r4, 4));
  EXPECT_FALSE(HasRule(r4, 1));
}

// Over many seeded lines of 60 units: stable ones raise a signal about as often as the rules' false-alarm rate says
// and no more, drifting ones (0.1 sigma more per unit from the middle on) nearly always. The rules' in-control
// average run length of ~92 points (Champ & Woodall 1987) makes P(some signal in 60) ~ 1 - exp(-60/92) = 0.48; the
// bound 0.7 leaves room for limits estimated from the data; a drift of 3 sigma over 30 units must be caught >= 90 %.
TEST(ControlChart, DriftIsFlaggedAndStableLinesOnlyAtTheFalseAlarmRate) {
  constexpr int kLines = 400, kUnits = 60;
  constexpr double kMaxStableSignalFraction = 0.7, kMinDriftSignalFraction = 0.9;
  std::mt19937 rng(12);
  std::normal_distribution<double> z(0.0, 1.0);
  int stable_flagged = 0, drift_flagged = 0, drift_flagged_late = 0, stable_rule1 = 0;
  for (int line = 0; line < kLines; ++line) {
    std::vector<double> stable, drifting;
    for (int i = 0; i < kUnits; ++i) {
      const double noise = z(rng);
      stable.push_back(noise);
      drifting.push_back(noise + (i >= kUnits / 2 ? 0.1 * (i - kUnits / 2 + 1) : 0.0));
    }
    const auto s = IndividualsChart(stable);
    const auto d = IndividualsChart(drifting);
    ASSERT_TRUE(s && d);
    stable_flagged += s->signals.empty() ? 0 : 1;
    stable_rule1 += HasRule(*s, 1) ? 1 : 0;
    drift_flagged += d->signals.empty() ? 0 : 1;
    drift_flagged_late += (!d->signals.empty() && d->signals.back().index >= kUnits / 2) ? 1 : 0;
  }
  // measured 2026-12-01: stable 182/400 = 0.46 flagged (rule 1 alone 67/400 = 0.17), drifting 399/400, all of
  // them in the drifting half.
  EXPECT_LT(stable_flagged, kMaxStableSignalFraction * kLines);
  EXPECT_GT(drift_flagged_late, kMinDriftSignalFraction * kLines);
  // Rule 1 alone: 0.27 % of points beyond 3 sigma, P(some in 60) = 0.15; with data limits a little lower or higher.
  EXPECT_LT(stable_rule1, 0.3 * kLines);
  EXPECT_GE(drift_flagged, drift_flagged_late);
}


// Subgroups merged pairwise hold what one subgroup of all their values would (the charts of a long series merge
// neighbours as it grows).
TEST(SubgroupMeansChart, MergedSubgroupsEqualOneOfAllTheirValues) {
  std::mt19937 rng(3);
  std::normal_distribution<double> z(0.01, 0.002);
  Subgroup whole, left, right;
  for (int i = 0; i < 37; ++i) {
    const double v = z(rng);
    const bool included = i % 5 != 0;
    whole.Add(v, included);
    (i < 20 ? left : right).Add(v, included);
  }
  left.Merge(right);
  EXPECT_EQ(left.n, whole.n);
  EXPECT_EQ(left.n_in, whole.n_in);
  // Round-off of two running sums of ~40 values of 1e-2 (a few ulps).
  EXPECT_NEAR(left.mean, whole.mean, 1e-16);
  EXPECT_NEAR(left.mean_in, whole.mean_in, 1e-16);
  EXPECT_NEAR(left.m2_in, whole.m2_in, 1e-18);
}

// Limits by hand: 20 subgroups of 4 units -1, +1, -1, +1 about their means, which alternate 5 -+ 0.1 (centre 5, no
// run on one side); each subgroup's squared deviations 4 over 3 degrees of freedom, so sigma = sqrt(80 / 60); a
// point's limits are 3 sigma / sqrt(4).
TEST(SubgroupMeansChart, PooledSigmaAndEachPointAgainstItsOwnSize) {
  std::vector<Subgroup> groups(20);
  for (std::size_t k = 0; k < groups.size(); ++k) {
    for (double v : {-1.0, 1.0, -1.0, 1.0}) groups[k].Add(5 + (k % 2 ? 0.1 : -0.1) + v, true);
  }
  auto c = SubgroupMeansChart(groups);
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(c->centre, 5, 1e-14);
  EXPECT_NEAR(c->sigma, std::sqrt(80.0 / 60.0), 1e-14);
  EXPECT_EQ(c->subgroup_size, 4);
  EXPECT_EQ(c->limit_points, 80);
  EXPECT_NEAR(c->Ucl(), 5 + 3 * std::sqrt(80.0 / 60.0) / 2, 1e-14);
  EXPECT_TRUE(c->signals.empty());
  // A last subgroup of one unit 2 sigma above the centre: within its own limits (3 sigma / sqrt(1)), but the same
  // value as the mean of four would be beyond 3 sigma / sqrt(4).
  Subgroup one;
  one.Add(5 + 2 * c->sigma, true);
  groups.push_back(one);
  c = SubgroupMeansChart(groups);
  ASSERT_TRUE(c.has_value());
  EXPECT_TRUE(c->signals.empty());
  groups.back() = Subgroup();
  for (int k = 0; k < 4; ++k) groups.back().Add(5 + 2 * c->sigma, k < 3);  // the fourth excluded (a FAIL unit)
  c = SubgroupMeansChart(groups);
  ASSERT_TRUE(c.has_value());
  ASSERT_FALSE(c->signals.empty());
  EXPECT_EQ(c->signals.front().index, 20);
  EXPECT_EQ(c->signals.front().rule, 1);
  // Too few subgroups with a passing unit: no chart.
  EXPECT_FALSE(SubgroupMeansChart(std::vector<Subgroup>(groups.begin(), groups.begin() + 7)).has_value());
}

}  // namespace
}  // namespace topocal::report
