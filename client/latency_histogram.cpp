#include "latency_histogram.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace kugel::client {

namespace {

constexpr double lowest = 1e-6; ///< s: the first bucket's lower edge
constexpr double highest = 1e3; ///< s: the last bucket holds everything above
constexpr double growth = 1.02; ///< each bucket 2 % wider than the one before

std::size_t bucket_count()
{
    return static_cast<std::size_t>(std::ceil(std::log(highest / lowest) / std::log(growth))) + 1;
}

std::size_t bucket_of(double seconds, std::size_t buckets)
{
    if (!(seconds > lowest))
        return 0;
    auto const i = static_cast<std::size_t>(std::log(seconds / lowest) / std::log(growth));
    return std::min(i, buckets - 1);
}

/// The middle (geometric) of bucket i.
double middle_of(std::size_t i)
{
    return lowest * std::pow(growth, static_cast<double>(i) + 0.5);
}

} // namespace

latency_histogram::latency_histogram() : buckets_(bucket_count(), 0) {}

void latency_histogram::record(double seconds)
{
    seconds = std::max(seconds, 0.0);
    ++buckets_[bucket_of(seconds, buckets_.size())];
    min_ = count_ == 0 ? seconds : std::min(min_, seconds);
    max_ = count_ == 0 ? seconds : std::max(max_, seconds);
    ++count_;
    sum_ += seconds;
}

void latency_histogram::merge(latency_histogram const& other)
{
    if (other.count_ == 0)
        return;
    for (std::size_t i = 0; i < buckets_.size(); ++i)
        buckets_[i] += other.buckets_[i];
    min_ = count_ == 0 ? other.min_ : std::min(min_, other.min_);
    max_ = count_ == 0 ? other.max_ : std::max(max_, other.max_);
    count_ += other.count_;
    sum_ += other.sum_;
}

double latency_histogram::mean() const
{
    return count_ == 0 ? 0.0 : sum_ / static_cast<double>(count_);
}

double latency_histogram::quantile(double q) const
{
    if (count_ == 0)
        return 0.0;
    q = std::clamp(q, 0.0, 1.0);
    // The sample of rank ceil(q·n) (at least the first), as in the nearest-rank method.
    auto const rank = std::max<std::uint64_t>(
        1, static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_))));
    if (rank == count_)
        return max_; // the largest sample is known exactly
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i + 1 < buckets_.size(); ++i) {
        seen += buckets_[i];
        if (seen >= rank)
            return std::clamp(middle_of(i), min_, max_);
    }
    return max_; // the last bucket is open above
}

} // namespace kugel::client
