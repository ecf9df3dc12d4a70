#include "physics/body_storage.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace kugel::physics {
namespace {

body_desc at(double x) { return {vec3(x, 0, 0), vec3::Zero(), 1.0, 0.0, 0.0, false}; }

TEST(MassFromDensity, IsDensityTimesSphereVolume)
{
    // m = ρ·4/3·π·r³; water (1000 kg/m³) in a sphere of radius 0.1 m. The two sides round
    // differently (0.1³ is not 1e-3 in binary): a few ulps, 1e-15 relative.
    double const expected = 1000.0 * 4.0 / 3.0 * std::numbers::pi * 1e-3;
    EXPECT_NEAR(mass_from_density(1000.0, 0.1), expected, 1e-15 * expected);
    EXPECT_EQ(mass_from_density(1000.0, 0.0), 0.0);
}

TEST(BodyStorage, AddGivesDistinctLiveIds)
{
    body_storage bodies;
    body_id const a = bodies.add(at(1));
    body_id const b = bodies.add(at(2));
    EXPECT_NE(a, b);
    EXPECT_FALSE(is_null(a));
    EXPECT_TRUE(bodies.contains(a));
    EXPECT_EQ(bodies.size(), 2U);
    EXPECT_EQ(bodies.positions()[*bodies.slot_of(b)].x(), 2.0);
}

TEST(BodyStorage, RemoveKeepsOtherIdsPointingAtTheirBodies)
{
    body_storage bodies;
    body_id const a = bodies.add(at(1));
    body_id const b = bodies.add(at(2));
    body_id const c = bodies.add(at(3));
    ASSERT_TRUE(bodies.remove(a)); // moves c into a's slot
    EXPECT_FALSE(bodies.contains(a));
    EXPECT_EQ(bodies.size(), 2U);
    EXPECT_EQ(bodies.positions()[*bodies.slot_of(b)].x(), 2.0);
    EXPECT_EQ(bodies.positions()[*bodies.slot_of(c)].x(), 3.0);
    EXPECT_EQ(bodies.ids()[*bodies.slot_of(c)], c);
}

TEST(BodyStorage, ReusedSlotGetsNewGenerationSoStaleIdsStayDead)
{
    body_storage bodies;
    body_id const a = bodies.add(at(1));
    ASSERT_TRUE(bodies.remove(a));
    body_id const b = bodies.add(at(2));
    EXPECT_EQ(b.index, a.index);
    EXPECT_NE(b.generation, a.generation);
    EXPECT_FALSE(bodies.contains(a));
    EXPECT_FALSE(bodies.remove(a));
    EXPECT_TRUE(bodies.contains(b));
}

TEST(BodyStorage, NullAndUnknownIdsNameNothing)
{
    body_storage bodies;
    bodies.add(at(1));
    EXPECT_FALSE(bodies.contains(body_id{}));
    EXPECT_FALSE(bodies.contains(body_id{7, 1}));
    EXPECT_FALSE(bodies.remove(body_id{7, 1}));
}

TEST(BodyStorage, StaticBodyHasZeroInverseMassButKeepsItsMass)
{
    body_storage bodies;
    body_id const sun = bodies.add({vec3::Zero(), vec3::Zero(), 5.0, 1.0, 0.0, true});
    auto const slot = *bodies.slot_of(sun);
    EXPECT_EQ(bodies.inverse_masses()[slot], 0.0);
    EXPECT_EQ(bodies.masses()[slot], 5.0);
    EXPECT_TRUE(bodies.describe(slot).is_static);
}

TEST(BodyStorage, RefusesBadBodiesAndNamesTheField)
{
    body_storage bodies;
    double const nan = std::numeric_limits<double>::quiet_NaN();
    auto refuses = [&](body_desc const& d, std::string const& word) {
        try {
            bodies.add(d);
            ADD_FAILURE() << "accepted a body with bad " << word;
        } catch (std::invalid_argument const& e) {
            EXPECT_NE(std::string(e.what()).find(word), std::string::npos) << e.what();
        }
    };
    refuses({vec3(nan, 0, 0), vec3::Zero(), 1.0, 0.0, 0.0, false}, "position");
    refuses({vec3::Zero(), vec3(0, INFINITY, 0), 1.0, 0.0, 0.0, false}, "velocity");
    refuses({vec3::Zero(), vec3::Zero(), 1.0, -1.0, 0.0, false}, "radius");
    refuses({vec3::Zero(), vec3::Zero(), 0.0, 0.0, 0.0, false}, "mass");
    refuses({vec3::Zero(), vec3::Zero(), -2.0, 0.0, 0.0, false}, "mass");
    refuses({vec3::Zero(), vec3::Zero(), 1e-320, 0.0, 0.0, false}, "mass");
    refuses({vec3::Zero(), vec3(1, 0, 0), 1.0, 0.0, 0.0, true}, "velocity");
    refuses({vec3::Zero(), vec3::Zero(), 1.0, 0.0, nan, false}, "charge");
    EXPECT_TRUE(bodies.empty()); // nothing half-added
}

// permute() moves every quantity of a body together, and its id follows it: the body in slot
// order[k] is in slot k after, and slot_of() finds it there.
TEST(BodyStorage, PermuteMovesEveryQuantityAndKeepsIds)
{
    body_storage bodies;
    std::vector<body_id> ids;
    for (int i = 0; i < 5; ++i)
        ids.push_back(bodies.add({vec3(i, 10 + i, 0), vec3(0, 0, i), 1.0 + i, 0.1 * i, -1.0 * i, false}));
    ASSERT_TRUE(bodies.remove(ids[1])); // a hole, filled by the last body: slots are 0 4 2 3
    std::vector<std::uint32_t> const order = {3, 0, 2, 1};
    std::vector<body_desc> before;
    std::vector<body_id> ids_before;
    for (std::size_t slot = 0; slot < bodies.size(); ++slot) {
        before.push_back(bodies.describe(slot));
        ids_before.push_back(bodies.ids()[slot]);
    }
    bodies.permute(order);
    ASSERT_EQ(bodies.size(), 4U);
    for (std::size_t k = 0; k < order.size(); ++k) {
        body_desc const moved = bodies.describe(k);
        body_desc const& was = before[order[k]];
        EXPECT_EQ(moved.position, was.position);
        EXPECT_EQ(moved.velocity, was.velocity);
        EXPECT_EQ(moved.mass, was.mass);
        EXPECT_EQ(moved.radius, was.radius);
        EXPECT_EQ(moved.charge, was.charge);
        EXPECT_EQ(bodies.inverse_masses()[k], 1.0 / was.mass);
        EXPECT_EQ(bodies.ids()[k], ids_before[order[k]]);
        EXPECT_EQ(bodies.slot_of(ids_before[order[k]]).value_or(99), k);
    }
    EXPECT_FALSE(bodies.contains(ids[1]));
    // The ids still work: removing one moves the last body into its slot, as before.
    ASSERT_TRUE(bodies.remove(ids[3]));
    EXPECT_EQ(bodies.positions()[*bodies.slot_of(ids[4])].x(), 4.0);
}

TEST(BodyStorage, PermuteRefusesWhatIsNotAPermutationAndMovesNothing)
{
    body_storage bodies;
    for (int i = 0; i < 3; ++i)
        bodies.add(at(i));
    auto refuses = [&](std::vector<std::uint32_t> const& order, std::string const& words) {
        try {
            bodies.permute(order);
            ADD_FAILURE() << "accepted a bad order naming " << words;
        } catch (std::invalid_argument const& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
        }
        for (std::size_t slot = 0; slot < 3; ++slot)
            EXPECT_EQ(bodies.positions()[slot].x(), static_cast<double>(slot));
    };
    refuses({0, 1}, "every slot");
    refuses({0, 1, 3}, "beyond the last");
    refuses({0, 2, 2}, "twice");
}

// The layout number changes with every change of what a slot holds (an addition, a removal,
// a permutation, a refused one aside) and with nothing else: a body removed and another added
// in its place leave as many bodies, yet a new layout.
TEST(BodyStorage, LayoutChangesWhenASlotMayHoldAnotherBody)
{
    body_storage bodies;
    std::vector<std::uint64_t> seen{bodies.layout()};
    auto const changed = [&] {
        bool const fresh = std::find(seen.begin(), seen.end(), bodies.layout()) == seen.end();
        seen.push_back(bodies.layout());
        return fresh;
    };
    EXPECT_NE(bodies.layout(), 0U);
    body_id const a = bodies.add(at(0));
    EXPECT_TRUE(changed());
    bodies.add(at(1));
    EXPECT_TRUE(changed());
    bodies.positions()[0].x() = 5.0; // a state, not a slot
    bodies.velocities()[1].y() = 2.0;
    EXPECT_FALSE(changed());
    EXPECT_TRUE(bodies.remove(a));
    EXPECT_TRUE(changed());
    EXPECT_FALSE(bodies.remove(a)); // nothing removed
    EXPECT_FALSE(changed());
    bodies.add(at(2)); // as many bodies as before the removal
    EXPECT_TRUE(changed());
    std::vector<std::uint32_t> const swap{1, 0};
    bodies.permute(swap);
    EXPECT_TRUE(changed());
    EXPECT_THROW(bodies.permute(std::vector<std::uint32_t>{0, 0}), std::invalid_argument);
    EXPECT_FALSE(changed());
}

// A storage keeps no column of charges until a body carries one: then every body has its
// charge (0 for the others), through removals and permutations, and a description gives it.
TEST(BodyStorage, ChargesAreKeptOnceABodyCarriesOne)
{
    body_storage bodies;
    for (int i = 0; i < 3; ++i)
        bodies.add(at(i));
    EXPECT_TRUE(bodies.charges().empty());
    EXPECT_EQ(bodies.charge(1), 0.0);
    EXPECT_EQ(bodies.describe(2).charge, 0.0);

    body_desc charged = at(3);
    charged.charge = -2.5;
    body_id const q = bodies.add(charged);
    ASSERT_EQ(bodies.charges().size(), 4U);
    EXPECT_EQ(bodies.charges()[0], 0.0);
    EXPECT_EQ(bodies.charges()[3], -2.5);

    EXPECT_TRUE(bodies.remove(bodies.ids()[0])); // the charged body moves into slot 0
    ASSERT_EQ(bodies.charges().size(), 3U);
    EXPECT_EQ(bodies.charge(*bodies.slot_of(q)), -2.5);
    std::vector<std::uint32_t> const order{2, 0, 1};
    bodies.permute(order);
    EXPECT_EQ(bodies.charge(*bodies.slot_of(q)), -2.5);
    EXPECT_EQ(bodies.describe(*bodies.slot_of(q)).charge, -2.5);
    double total = 0.0;
    for (double const c : bodies.charges())
        total += c;
    EXPECT_EQ(total, -2.5) << "the others carry none";
    bodies.add(at(5)); // after the column exists, an uncharged body gets its 0 there
    EXPECT_EQ(bodies.charges().size(), 4U);

    body_storage first; // the very first body charged
    first.add(charged);
    ASSERT_EQ(first.charges().size(), 1U);
    EXPECT_EQ(first.charges()[0], -2.5);
}

} // namespace
} // namespace kugel::physics
