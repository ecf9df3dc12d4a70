#include "sensors.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace kugel::physics {

bool sensor::contains(vec3 const& x) const
{
    if (kind == shape::box)
        return (x.array() >= box.min.array()).all() && (x.array() <= box.max.array()).all();
    return (x - centre).squaredNorm() <= radius * radius;
}

aabb sensor::bounds() const
{
    if (kind == shape::box)
        return box;
    vec3 const r = vec3::Constant(radius);
    return {centre - r, centre + r};
}

std::optional<const char*> sensor::invalid() const
{
    if (kind == shape::box) {
        if (!box.min.allFinite() || !box.max.allFinite())
            return "a sensor's box must be finite";
        if (!(box.min.array() <= box.max.array()).all())
            return "a sensor's box needs min <= max on every axis";
        return std::nullopt;
    }
    if (!centre.allFinite())
        return "a sensor's centre must be finite";
    if (!(radius > 0.0) || !std::isfinite(radius * radius))
        return "a sensor's radius must be > 0 and finite";
    return std::nullopt;
}

namespace {

double evaluate(double const* c, int degree, double s)
{
    double value = c[degree];
    for (int k = degree - 1; k >= 0; --k)
        value = value * s + c[k];
    return value;
}

/// The root in (lo, hi) of a polynomial of opposite signs at the two ends, by bisection
/// until the bracket cannot shrink.
double bracketed_root(double const* c, int degree, double lo, double hi, bool rising)
{
    for (int k = 0; k < 200; ++k) {
        double const mid = lo + 0.5 * (hi - lo);
        if (!(mid > lo && mid < hi))
            break;
        double const value = evaluate(c, degree, mid);
        if (value == 0.0)
            return mid;
        if ((value < 0.0) == rising)
            lo = mid;
        else
            hi = mid;
    }
    return lo + 0.5 * (hi - lo);
}

} // namespace

void sign_changes(double const* c, int degree, double lo, double hi, std::vector<double>& out)
{
    while (degree > 0 && c[degree] == 0.0)
        --degree;
    if (degree == 0 || !(lo < hi))
        return;
    // Between two neighbouring roots of the derivative the polynomial is monotone: at most
    // one sign change there.
    std::array<double, 4> derivative{};
    for (int k = 1; k <= degree; ++k)
        derivative[static_cast<std::size_t>(k - 1)] = k * c[k];
    std::vector<double> stops{lo};
    std::vector<double> turns;
    sign_changes(derivative.data(), degree - 1, lo, hi, turns);
    stops.insert(stops.end(), turns.begin(), turns.end());
    stops.push_back(hi);
    for (std::size_t k = 0; k + 1 < stops.size(); ++k) {
        double const a = stops[k], b = stops[k + 1];
        double const fa = evaluate(c, degree, a), fb = evaluate(c, degree, b);
        if ((fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0))
            out.push_back(bracketed_root(c, degree, a, b, fa < 0.0));
        else if (fa == 0.0 && k > 0) {
            // a root exactly at a turn: a crossing only where the sign differs on its sides
            double const before = evaluate(c, degree, 0.5 * (stops[k - 1] + a));
            if ((before < 0.0 && fb > 0.0) || (before > 0.0 && fb < 0.0))
                out.push_back(a);
        }
    }
}

bool follow_sensor(sensor const& s, std::uint32_t index, body_id body, body_path const& path, double from,
                   double until, bool inside, double offset, std::vector<sensor_event>& out,
                   std::optional<vec3> const& end)
{
    // Where the centre may cross the boundary: the sign changes of the boundary's polynomials
    // in s = t − path.t (a box's six faces, each of degree 2; a ball's |x(s) − c|² − R², of
    // degree 4). Whether it is in between them is asked of contains() itself.
    double const lo = from - path.t, hi = until - path.t;
    std::vector<double> crossings;
    vec3 const half_a = 0.5 * path.a;
    if (s.kind == sensor::shape::box) {
        for (int axis = 0; axis < 3; ++axis) {
            for (double const bound : {s.box.min[axis], s.box.max[axis]}) {
                std::array<double, 3> const c{path.x[axis] - bound, path.v[axis], half_a[axis]};
                sign_changes(c.data(), 2, lo, hi, crossings);
            }
        }
    } else {
        vec3 const d = path.x - s.centre;
        std::array<double, 5> const c{d.squaredNorm() - s.radius * s.radius, 2.0 * d.dot(path.v),
                                      path.v.squaredNorm() + 2.0 * d.dot(half_a), 2.0 * path.v.dot(half_a),
                                      half_a.squaredNorm()};
        sign_changes(c.data(), 4, lo, hi, crossings);
    }
    std::sort(crossings.begin(), crossings.end());
    crossings.erase(std::unique(crossings.begin(), crossings.end()), crossings.end());

    auto const note = [&](double at, bool entered) {
        out.push_back({offset + path.t + at, index, body, entered});
        inside = entered;
    };
    double start = lo;
    for (std::size_t k = 0; k <= crossings.size(); ++k) {
        double const stop = k < crossings.size() ? crossings[k] : hi;
        bool const in = s.contains(path.x + (0.5 * (start + stop)) * path.v +
                                   (0.5 * (start + stop)) * (0.5 * (start + stop)) * half_a);
        if (in != inside)
            note(start, in);
        start = stop;
    }
    bool const in_at_end = s.contains(end ? *end : path.position_at(until));
    if (in_at_end != inside)
        note(hi, in_at_end);
    return inside;
}

} // namespace kugel::physics
