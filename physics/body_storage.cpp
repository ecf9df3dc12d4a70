#include "body_storage.hpp"

#include "physics/continuous/event.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace kugel::physics {

static_assert(body_storage::most_bodies <= continuous::event::most_indexed);

double mass_from_density(double density, double radius)
{
    return density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
}

namespace {

void require(bool ok, char const* what)
{
    if (!ok)
        throw std::invalid_argument(what);
}

} // namespace

body_id body_storage::add(body_desc const& d)
{
    require(d.position.allFinite(), "body position must be finite");
    require(d.velocity.allFinite(), "body velocity must be finite");
    require(std::isfinite(d.radius) && d.radius >= 0.0, "body radius must be finite and >= 0");
    require(std::isfinite(d.charge), "body charge must be finite");
    require(std::isfinite(d.mass), "body mass must be finite");
    if (d.is_static) {
        require(d.mass >= 0.0, "static body mass must be >= 0");
        require(d.velocity.isZero(0.0), "static body velocity must be zero");
    } else {
        require(d.mass > 0.0, "dynamic body mass must be > 0");
        require(std::isfinite(1.0 / d.mass), "dynamic body mass is too small: 1/m overflows");
    }

    std::uint32_t index = 0;
    if (!free_indices_.empty()) {
        index = free_indices_.back();
        free_indices_.pop_back();
    } else {
        if (sparse_.size() >= most_bodies)
            throw std::length_error("body_storage is full: 2^30 bodies");
        index = static_cast<std::uint32_t>(sparse_.size());
        sparse_.emplace_back();
    }
    slot_entry& entry = sparse_[index];
    entry.dense = static_cast<std::uint32_t>(positions_.size());
    body_id const id{index, entry.generation};

    positions_.push_back(d.position);
    velocities_.push_back(d.velocity);
    inverse_masses_.push_back(d.is_static ? 0.0 : 1.0 / d.mass);
    radii_.push_back(d.radius);
    masses_.push_back(d.mass);
    if (!charges_.empty()) {
        charges_.push_back(d.charge);
    } else if (d.charge != 0.0) { // the first charge: the others carry none
        charges_.assign(positions_.size() - 1, 0.0);
        charges_.push_back(d.charge);
    }
    ids_.push_back(id);
    ++layout_;
    return id;
}

std::optional<std::size_t> body_storage::slot_of(body_id id) const
{
    if (id.index >= sparse_.size())
        return std::nullopt;
    slot_entry const& entry = sparse_[id.index];
    if (entry.dense == slot_entry::dead || entry.generation != id.generation)
        return std::nullopt;
    return entry.dense;
}

bool body_storage::remove(body_id id)
{
    auto const slot = slot_of(id);
    if (!slot)
        return false;
    std::size_t const hole = *slot;
    std::size_t const last = positions_.size() - 1;
    if (hole != last) {
        positions_[hole] = positions_[last];
        velocities_[hole] = velocities_[last];
        inverse_masses_[hole] = inverse_masses_[last];
        radii_[hole] = radii_[last];
        masses_[hole] = masses_[last];
        if (!charges_.empty())
            charges_[hole] = charges_[last];
        ids_[hole] = ids_[last];
        sparse_[ids_[hole].index].dense = static_cast<std::uint32_t>(hole);
    }
    positions_.pop_back();
    velocities_.pop_back();
    inverse_masses_.pop_back();
    radii_.pop_back();
    masses_.pop_back();
    if (!charges_.empty())
        charges_.pop_back();
    ids_.pop_back();

    slot_entry& entry = sparse_[id.index];
    entry.dense = slot_entry::dead;
    // Skip generation 0 on wrap-around: it is the null id.
    entry.generation = entry.generation == 0xffffffffU ? 1U : entry.generation + 1U;
    free_indices_.push_back(id.index);
    ++layout_;
    return true;
}

namespace {

/// column[order[k]] for every k, as the new column; `spare` is left holding the old one,
/// so that the next column of its type is gathered into memory already in use.
template <class T>
void gather(std::vector<T>& column, std::vector<T>& spare, std::span<std::uint32_t const> order,
            parallel_for* loops)
{
    spare.resize(column.size());
    run_chunks(loops, order.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k)
            spare[k] = column[order[k]];
    });
    column.swap(spare);
}

} // namespace

void body_storage::permute(std::span<std::uint32_t const> order, parallel_for* loops)
{
    std::size_t const n = size();
    require(order.size() == n, "a permutation of the bodies must name every slot");
    std::vector<std::uint8_t>& named = spare_bytes_;
    named.assign(n, 0);
    for (std::uint32_t const slot : order) {
        require(slot < n, "a permutation of the bodies names a slot beyond the last");
        require(named[slot] == 0, "a permutation of the bodies names a slot twice");
        named[slot] = 1;
    }
    gather(positions_, spare_vectors_, order, loops);
    gather(velocities_, spare_vectors_, order, loops);
    gather(inverse_masses_, spare_numbers_, order, loops);
    gather(radii_, spare_numbers_, order, loops);
    gather(masses_, spare_numbers_, order, loops);
    if (!charges_.empty())
        gather(charges_, spare_numbers_, order, loops);
    gather(ids_, spare_ids_, order, loops);
    ++layout_;
    run_chunks(loops, n, [&](std::size_t, std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k)
            sparse_[ids_[k].index].dense = static_cast<std::uint32_t>(k);
    });
}

void body_storage::reserve(std::size_t n)
{
    positions_.reserve(n);
    velocities_.reserve(n);
    inverse_masses_.reserve(n);
    radii_.reserve(n);
    masses_.reserve(n);
    if (!charges_.empty())
        charges_.reserve(n);
    ids_.reserve(n);
    sparse_.reserve(n);
}

body_desc body_storage::describe(std::size_t slot) const
{
    return {positions_[slot], velocities_[slot], masses_[slot],
            radii_[slot],     charge(slot),    inverse_masses_[slot] == 0.0};
}

} // namespace kugel::physics
