#include "time_of_impact.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cmath>

// The times of impact lean on fma, which the library computes in software where the
// compiler may not assume the instruction; it is exactly rounded either way, so a version
// compiled for processors that have it gives the same bits, and is chosen at load. The
// helpers below are inlined into both versions, so that the fast one has them too.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define KUGEL_WITH_FMA_WHERE_PRESENT [[gnu::target_clones("fma", "default")]]
#else
#define KUGEL_WITH_FMA_WHERE_PRESENT
#endif

namespace kugel::physics {

namespace {

// Error-free transformations: hi + lo is exactly a + b, resp. a · b.
struct double_double
{
    double hi;
    double lo;
};

[[gnu::always_inline]] inline double_double two_sum(double a, double b)
{
    double const s = a + b;
    double const z = s - a;
    return {s, (a - (s - z)) + (b - z)};
}

[[gnu::always_inline]] inline double_double two_product(double a, double b)
{
    double const p = a * b;
    return {p, std::fma(a, b, -p)};
}

/// Σ x_k·y_k as accurate as if computed in twice the precision and then rounded (Ogita,
/// Rump and Oishi's Dot2). Used where the terms nearly cancel: the squared gap between two
/// nearly touching spheres, the distance of a sphere resting on a wall, the sign of d·v.
template <std::size_t n>
[[gnu::always_inline]] inline double accurate_dot(std::array<double, n> const& x, std::array<double, n> const& y)
{
    double_double const first = two_product(x[0], y[0]);
    double sum = first.hi;
    double error = first.lo;
    for (std::size_t k = 1; k < n; ++k) {
        double_double const product = two_product(x[k], y[k]);
        double_double const partial = two_sum(sum, product.hi);
        sum = partial.hi;
        error += partial.lo + product.lo;
    }
    return sum + error;
}

/// std::ilogb(x) for x > 0: the exponent field itself for a normal x, the library's answer
/// for the rest (subnormal, infinite).
int exponent_of(double x)
{
    auto const field = static_cast<int>((std::bit_cast<std::uint64_t>(x) >> 52U) & 0x7ffU);
    return field != 0 && field != 0x7ff ? field - 1023 : std::ilogb(x);
}

/// std::ldexp(x, e): for e within the normal exponents, the product with 2^e, which is
/// rounded (should it fall below the normal range) exactly as ldexp rounds, to nearest.
double times_power_of_two(double x, int e)
{
    if (e < -1022 || e > 1023)
        return std::ldexp(x, e);
    return x * std::bit_cast<double>(static_cast<std::uint64_t>(e + 1023) << 52U);
}

std::array<double, 3> components(vec3 const& v)
{
    return {v.x(), v.y(), v.z()};
}

/// a·b − c·d to within 1.5 units in the last place (Kahan's algorithm with one fma): the
/// discriminant of a quadratic without cancellation.
[[gnu::always_inline]] inline double difference_of_products(double a, double b, double c, double d)
{
    double const cd = c * d;
    double const error = std::fma(-c, d, cd);
    return std::fma(a, b, -cd) + error;
}

} // namespace

double plane_contact_time_linear(plane const& wall, double radius, vec3 const& x_i, double t_i,
                                 vec3 const& x_next, double t_next)
{
    double const contact = wall.offset + radius * wall.normal.norm(); // d + r‖n‖
    double const height_i = wall.normal.dot(x_i);                     // n·x_i
    double const height_next = wall.normal.dot(x_next);               // n·x_{i+1}
    double const denominator = height_i - height_next;
    if (denominator == 0.0)
        return t_i;
    // The lecture's weights w_i = (d + r‖n‖ − n·x_{i+1}) / (…) and w_{i+1} = (n·x_i − d −
    // r‖n‖) / (…) sum to 1, so t_coll = t_i + w_{i+1}·(t_{i+1} − t_i): the same value, but it
    // stays within [t_i, t_{i+1}] under the preconditions (0 <= w_{i+1} <= 1 holds after
    // rounding too) and does not lose t_{i+1} − t_i to a large t_i.
    double const weight_next = (height_i - contact) / denominator;
    return std::min(t_i + weight_next * (t_next - t_i), std::max(t_i, t_next));
}

KUGEL_WITH_FMA_WHERE_PRESENT
std::optional<double> plane_time_of_impact(plane const& wall, double radius, vec3 const& x,
                                           vec3 const& v, vec3 const& a, double t_max)
{
    if (!(t_max >= 0.0))
        return std::nullopt;

    // g(t) = n·x(t) − (d + r‖n‖) = gap + speed·t + half_accel·t² on the lecture's parabola
    // x(t) = x + v·t + a·t²/2; g > 0 is clear of the wall.
    vec3 const& n = wall.normal;
    double const gap = accurate_dot<5>({n.x(), n.y(), n.z(), -1.0, -radius},
                                       {x.x(), x.y(), x.z(), wall.offset, n.norm()});
    double const speed = accurate_dot<3>(components(n), components(v)); // n·v
    double const half_accel = 0.5 * n.dot(a);                           // n·a / 2

    bool const approaching = speed < 0.0 || (speed == 0.0 && half_accel < 0.0);
    if (gap <= 0.0 && approaching)
        return 0.0;
    // Touching or inside but not approaching: the contact now is not an impact, only a
    // later re-entry is.
    bool const zero_counts = gap > 0.0;

    // The root where g falls through zero: for an upward parabola (half_accel > 0) the
    // smaller root, for a downward one the larger, for a line the only one if speed < 0.
    double entering = 0.0;
    if (half_accel == 0.0) {
        if (!(speed < 0.0))
            return std::nullopt;
        entering = gap / -speed;
    } else {
        // A t² + B t + C = 0 with A = half_accel, B = speed, C = gap. Numerical Recipes'
        // form: q = −(B + sign(B)·√(B² − 4AC)) / 2, roots q/A and C/q. The sum in q never
        // cancels, and for a tiny |A| the near root C/q stays accurate while q/A runs off
        // towards infinity (the parabola becomes the line).
        double const discriminant = difference_of_products(speed, speed, 4.0 * half_accel, gap);
        if (discriminant < 0.0)
            return std::nullopt; // g never reaches zero
        double const q = -0.5 * (speed + std::copysign(std::sqrt(discriminant), speed));
        double const root_1 = q / half_accel;
        double const root_2 = q == 0.0 ? 0.0 : gap / q; // q = 0 only for the double root 0
        entering = half_accel > 0.0 ? std::min(root_1, root_2) : std::max(root_1, root_2);
    }

    if (entering < 0.0 || entering > t_max || (entering == 0.0 && !zero_counts))
        return std::nullopt;
    return entering;
}

KUGEL_WITH_FMA_WHERE_PRESENT
std::optional<double> sphere_time_of_impact(vec3 const& x1, vec3 const& v1, double r1,
                                            vec3 const& x2, vec3 const& v2, double r2,
                                            double t_max)
{
    if (!(t_max >= 0.0))
        return std::nullopt;

    // The lecture's reduction: sphere 1 becomes a point moving with v₁ − v₂, sphere 2 a
    // resting sphere of radius r₁ + r₂. With d = x₁ − x₂ and v = v₁ − v₂, the point is on
    // that sphere when ‖d + v·t‖² = (r₁ + r₂)², i.e. a t² + 2 b t + c = 0 with a = v·v,
    // b = d·v and c = d·d − (r₁ + r₂)².
    double const reach = r1 + r2;
    vec3 const d = x1 - x2;
    vec3 const relative_velocity = v1 - v2;
    if (surely_misses(d, relative_velocity, reach))
        return std::nullopt;
    // The time scales as 1/|v|, so it is found for v scaled by a power of two to a largest
    // component in [1, 2), then scaled back. Power-of-two scaling is exact: for ordinary
    // speeds the result is bit for bit the unscaled one. Unscaled, a relative speed below
    // about 1e-154 made a R² (below) underflow to 0, and the time came out wrong (1.67/speed
    // instead of 1/speed for a 1 m gap); above about 1e154 it overflowed.
    double const largest = relative_velocity.cwiseAbs().maxCoeff();
    if (!(largest > 0.0))
        return std::nullopt; // no relative motion: no approach
    int const exponent = exponent_of(largest);
    vec3 const v = relative_velocity.unaryExpr([&](double x) { return times_power_of_two(x, -exponent); });
    double const b = accurate_dot<3>(components(d), components(v)); // d·v
    // Lecture: no hit when (x₂ − x₁)·v₁ < 0; also none for b = 0 (no approach).
    if (!(b < 0.0))
        return std::nullopt;

    // c = d·d − (r₁ + r₂)²: the difference of two nearly equal squares when the spheres
    // nearly touch, so summed in double-double.
    double const c = accurate_dot<4>({d.x(), d.y(), d.z(), reach}, {d.x(), d.y(), d.z(), -reach});
    if (c <= 0.0)
        return 0.0; // touching or overlapping, and approaching

    // Lecture: no hit when the closest approach exceeds the radius,
    //   (x₂ − x₁)² − [(x₂ − x₁)·v]² / v² > r²,
    // i.e. when b² − a c < 0. By Lagrange's identity b² − a c = a R² − ‖d × v‖², and that
    // form is the one computed: b² and a c are both about a‖d‖² and cancel whenever the
    // spheres are far apart compared with R, while a R² and ‖d × v‖² (a times the squared
    // distance of closest approach) only cancel for a grazing path, where the time itself is
    // ill-conditioned.
    vec3 const cross(difference_of_products(d.y(), v.z(), d.z(), v.y()),
                     difference_of_products(d.z(), v.x(), d.x(), v.z()),
                     difference_of_products(d.x(), v.y(), d.y(), v.x()));
    vec3 const v_reach = v * reach;
    double const discriminant =
        accurate_dot<6>({v_reach.x(), v_reach.y(), v_reach.z(), cross.x(), cross.y(), cross.z()},
                        {v_reach.x(), v_reach.y(), v_reach.z(), -cross.x(), -cross.y(), -cross.z()});
    if (discriminant < 0.0)
        return std::nullopt;

    // The lecture's t_coll = (v·(x₂ − x₁) − √([v·(x₁ − x₂)]² − v²[(x₁ − x₂)² − r²])) / v²
    // is (−b − √(b² − a c)) / a here. Its numerator subtracts two nearly equal numbers when
    // a c << b², that is when the gap is small compared with the distance the spheres travel
    // (a fast pair about to touch), and can lose every digit. Multiplying numerator and
    // denominator by (−b + √(b² − a c)) gives the same root as
    //   t = c / (−b + √(b² − a c)),
    // whose denominator is a sum of two non-negative terms (b < 0), so it never cancels, and
    // never divides by a.
    double const t = times_power_of_two(c / (-b + std::sqrt(discriminant)), -exponent);
    if (!(t <= t_max) || !std::isfinite(t))
        return std::nullopt;
    return t;
}

vec3 contact_point(vec3 const& x1_at_contact, double r1, vec3 const& x2_at_contact, double r2)
{
    double const reach = r1 + r2;
    if (reach == 0.0)
        return 0.5 * (x1_at_contact + x2_at_contact);
    // The lecture's weights, as printed, are the right way round: at contact
    // ‖x₂ − x₁‖ = r₁ + r₂, and x₁ + r₁/(r₁ + r₂)·(x₂ − x₁) = r₂/(r₁+r₂)·x₁ + r₁/(r₁+r₂)·x₂.
    return (r2 / reach) * x1_at_contact + (r1 / reach) * x2_at_contact;
}

} // namespace kugel::physics
