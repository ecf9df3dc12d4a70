#include "client/latency_histogram.hpp"

#include <gtest/gtest.h>

namespace kugel::client {
namespace {

TEST(LatencyHistogram, EmptyGivesZeros)
{
    latency_histogram h;
    EXPECT_EQ(h.count(), 0U);
    EXPECT_EQ(h.quantile(0.5), 0.0);
    EXPECT_EQ(h.max(), 0.0);
    EXPECT_EQ(h.mean(), 0.0);
}

TEST(LatencyHistogram, QuantilesAreWithinTwoPercentAndExtremesExact)
{
    latency_histogram h;
    for (int ms = 1; ms <= 100; ++ms) // 1 ms .. 100 ms
        h.record(ms * 1e-3);
    EXPECT_EQ(h.count(), 100U);
    EXPECT_EQ(h.min(), 1e-3);
    EXPECT_EQ(h.max(), 100e-3);
    EXPECT_NEAR(h.quantile(0.5), 50e-3, 50e-3 * 0.02);
    EXPECT_NEAR(h.quantile(0.99), 99e-3, 99e-3 * 0.02);
    EXPECT_EQ(h.quantile(1.0), 100e-3);
    EXPECT_NEAR(h.mean(), 50.5e-3, 1e-12);
}

TEST(LatencyHistogram, OneSampleIsEveryQuantile)
{
    latency_histogram h;
    h.record(0.0123);
    EXPECT_EQ(h.quantile(0.0), 0.0123);
    EXPECT_EQ(h.quantile(0.5), 0.0123);
    EXPECT_EQ(h.quantile(0.99), 0.0123);
}

TEST(LatencyHistogram, KeepsValuesOutsideItsRange)
{
    latency_histogram h;
    h.record(0.0);
    h.record(5000.0);
    EXPECT_EQ(h.min(), 0.0);
    EXPECT_EQ(h.max(), 5000.0);
    EXPECT_EQ(h.quantile(1.0), 5000.0);
}

TEST(LatencyHistogram, MergeIsAsIfRecordedTogether)
{
    latency_histogram a;
    latency_histogram b;
    latency_histogram both;
    for (int i = 1; i <= 50; ++i) {
        a.record(i * 1e-3);
        both.record(i * 1e-3);
    }
    for (int i = 51; i <= 100; ++i) {
        b.record(i * 1e-3);
        both.record(i * 1e-3);
    }
    a.merge(b);
    EXPECT_EQ(a.count(), both.count());
    EXPECT_EQ(a.min(), both.min());
    EXPECT_EQ(a.max(), both.max());
    EXPECT_EQ(a.quantile(0.5), both.quantile(0.5));
    EXPECT_EQ(a.quantile(0.99), both.quantile(0.99));
}

} // namespace
} // namespace kugel::client
