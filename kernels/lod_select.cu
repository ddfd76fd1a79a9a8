// SPDX-License-Identifier: MIT
#include "lod_select.h"

#include "box_projection.h"
#include "device_access.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/reduce.h>
#include <thrust/transform.h>
#include <thrust/transform_reduce.h>

#include <cmath>

namespace occ::k {

namespace {

// A not-drawn object's share: below every real share (which are >= 0).
constexpr float kNotDrawn = -1.0f;

// log of Eq. 1's share s_i = (A_i P_i / D_i)^((alpha-1)/alpha), or -inf when the object is
// not drawn. Logs keep (A P / D)^beta finite: with A ~ 1e7 px, P ~ 1e7 and D ~ 1e-2 the
// product alone is 1e16, and raising it to beta = 2 would already lose float's exponent range.
struct LogShare {
    const ObjectInfo* objects;
    const uint32_t* ids;
    Camera camera;
    float exponent;  // (alpha - 1) / alpha
    float pet;
    const float* visible_share;  // may be null

    OCC_HD float operator()(uint32_t j) const {
        const ObjectInfo& o = objects[ids[j]];
        if (o.vertex_count == 0) return -INFINITY;
        const Projection pr = projectBox(o, camera);
        const float area = pr.area, depth = pr.depth;
        if (area < pet) return -INFINITY;
        // What the occluders leave of the image weighs instead of all of it (pet still tests
        // the whole image: a mostly hidden object is drawn, coarser).
        const float seen = visible_share ? area * visible_share[j] : area;
        // With pet = 0 an object may be drawn with no area: a vanishing share, so it sits at its
        // floor, rather than log(0) = -inf, which would mean "not drawn".
        return exponent * (logf(fmaxf(seen, 1e-30f)) + logf(float(o.vertex_count)) - logf(depth));
    }
};

struct Maximum {
    OCC_HD float operator()(float a, float b) const { return fmaxf(a, b); }
};

// Shares relative to the largest, so the largest is 1 and none overflows; not-drawn objects
// get kNotDrawn. A share that underflows to 0 leaves its object at its floor.
struct NormalizeShare {
    float max_log;
    OCC_HD float operator()(float log_share) const {
        return log_share == -INFINITY ? kNotDrawn : expf(log_share - max_log);
    }
};

// The level one object gets for a given lambda, before rounding, and whether a bound fixed it.
struct Level {
    double value;
    bool free;  // strictly between floor and cap: moves with lambda
};

OCC_HD inline Level levelFor(double lambda, float share, uint32_t q, uint32_t p) {
    const double x = share > 0.0f ? lambda * double(share) : 0.0;
    if (x <= double(q)) return {double(q), false};
    if (x >= double(p)) return {double(p), false};
    return {x, true};
}

OCC_HD inline uint32_t rounded(double level) { return uint32_t(floor(level + 0.5)); }

struct Totals {
    uint64_t floors;     // sum of q over drawn objects
    uint64_t caps;       // sum of P
    double share_sum;
    double lambda_cap;   // smallest lambda at which every object with a positive share is capped
};

struct TotalsOf {
    const ObjectInfo* objects;
    const uint32_t* ids;
    const float* shares;
    OCC_HD Totals operator()(uint32_t j) const {
        const float s = shares[j];
        if (s == kNotDrawn) return {0, 0, 0.0, 0.0};
        const ObjectInfo& o = objects[ids[j]];
        const uint32_t q = o.q < o.vertex_count ? o.q : o.vertex_count;
        return {q, o.vertex_count, double(s), s > 0.0f ? double(o.vertex_count) / double(s) : 0.0};
    }
};

struct AddTotals {
    OCC_HD Totals operator()(const Totals& a, const Totals& b) const {
        return {a.floors + b.floors, a.caps + b.caps, a.share_sum + b.share_sum,
                a.lambda_cap > b.lambda_cap ? a.lambda_cap : b.lambda_cap};
    }
};

// Sum over objects of the levels at one lambda: the exact real sum and the slope (the shares of
// the free objects) drive a Newton step; the sum of rounded levels is what the budget bounds.
struct Evaluation {
    double level_sum;
    double free_share;
    uint64_t rounded_sum;
};

struct EvaluateAt {
    const ObjectInfo* objects;
    const uint32_t* ids;
    const float* shares;
    double lambda;
    OCC_HD Evaluation operator()(uint32_t j) const {
        const float s = shares[j];
        if (s == kNotDrawn) return {0.0, 0.0, 0};
        const ObjectInfo& o = objects[ids[j]];
        const uint32_t q = o.q < o.vertex_count ? o.q : o.vertex_count;
        const Level level = levelFor(lambda, s, q, o.vertex_count);
        return {level.value, level.free ? double(s) : 0.0, rounded(level.value)};
    }
};

struct AddEvaluations {
    OCC_HD Evaluation operator()(const Evaluation& a, const Evaluation& b) const {
        return {a.level_sum + b.level_sum, a.free_share + b.free_share, a.rounded_sum + b.rounded_sum};
    }
};

// lambda of the water-filling: the largest (to double precision, give or take a few vertices of
// rounding) at which the rounded levels still fit the budget. evaluate(lambda) is one pass over
// the objects.
template <class Evaluate>
double solveLambda(const Evaluate& evaluate, const Totals& totals, double budget) {
    if (double(totals.floors) >= budget || totals.share_sum <= 0.0) return 0.0;
    if (double(totals.caps) <= budget) return totals.lambda_cap;

    // f(lambda) = sum of clamp(lambda s_i, q_i, P_i) is piecewise linear and non-decreasing, so a
    // Newton step lands on the root of the current piece; bracketing, with geometric bisection
    // while the bracket spans orders of magnitude, keeps it converging when the set of clamped
    // objects changes on the way. Typically 4 to 8 passes.
    double lo = 0.0, hi = totals.lambda_cap;
    double lambda = budget / totals.share_sum < hi ? budget / totals.share_sum : hi;
    Evaluation e{};
    for (int iteration = 0; iteration < 100; ++iteration) {
        e = evaluate(lambda);
        (e.level_sum < budget ? lo : hi) = lambda;
        if (fabs(e.level_sum - budget) <= 1e-9 * budget || hi - lo <= 1e-13 * hi) break;
        double next = e.free_share > 0.0 ? lambda + (budget - e.level_sum) / e.free_share : -1.0;
        if (!(next > lo && next < hi)) next = lo > 0.0 && hi > 8.0 * lo ? sqrt(lo * hi) : 0.5 * (lo + hi);
        lambda = next;
    }

    // Rounding to nearest can put the sum above the budget by up to half the free objects: step
    // down by the excess over the slope until it fits (usually once). lambda = 0 always fits.
    for (int iteration = 0; iteration < 64 && double(e.rounded_sum) > budget; ++iteration) {
        double next = e.free_share > 0.0 ? lambda - (double(e.rounded_sum) - budget) / e.free_share : -1.0;
        if (!(next > 0.0 && next < lambda)) next = 0.5 * lambda;
        lambda = next;
        e = evaluate(lambda);
    }
    return double(e.rounded_sum) <= budget ? lambda : 0.0;
}

struct WriteCounts {
    const ObjectInfo* objects;
    const uint32_t* ids;
    const float* shares;
    const uint64_t* map_first;
    const uint32_t* maps;
    double lambda;
    uint32_t* vertex_count;
    uint32_t* triangle_count;
    OCC_HD void operator()(uint32_t j) const {
        const float s = shares[j];
        if (s == kNotDrawn) {
            vertex_count[j] = 0;
            triangle_count[j] = 0;
            return;
        }
        const ObjectInfo& o = objects[ids[j]];
        const uint32_t q = o.q < o.vertex_count ? o.q : o.vertex_count;
        const uint32_t vc = rounded(levelFor(lambda, s, q, o.vertex_count).value);
        vertex_count[j] = vc;
        triangle_count[j] = maps[map_first[o.mesh] + vc];
    }
};

// The error-bounded level of one object (lodSelectByError).
struct ErrorLevel {
    const ObjectInfo* objects;
    const uint32_t* ids;
    Camera camera;
    float tau, pet;
    const float* visible_share;  // may be null
    const uint64_t* map_first;
    const float* lod_error;
    const float* scale;
    const float* error_offset;  // may be null
    const uint32_t* maps;
    uint32_t* vertex_count;
    uint32_t* triangle_count;
    uint32_t* hint;  // by item: where the search starts, then the level found; may be null
    bool raise;  // lodRaiseToErrorBound: keep a finer level already chosen
    float raise_step;  // lodRaiseToErrorBound: raised levels on levelOnRaiseGrid's grid

    OCC_HD uint32_t operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        const ObjectInfo& o = objects[id];
        uint32_t k = 0;
        if (o.vertex_count > 0) {
            const Projection pr = projectBox(o, camera);
            if (pr.area >= pet) {
                // World units that project to tau pixels at the object's nearest depth.
                const float pixels_per_unit = float(camera.height) / (2.0f * tanf(0.5f * camera.fovy) * pr.depth);
                float allowed = tau / pixels_per_unit;
                // eps q / alpha <= tau: the less of it shows, the larger the error allowed.
                if (visible_share) allowed /= fmaxf(visible_share[j], 1e-30f);
                // What the item's input already gave up (an HLOD's node error) leaves the rest
                // to its level; none left: full detail (no level has a negative error).
                if (error_offset) allowed -= error_offset[id];
                allowed /= fmaxf(scale[id], 1e-30f);
                const float* e = lod_error + map_first[o.mesh];
                if (raise) {
                    // Level errors do not grow with the vertex count, so a chosen level within
                    // the bound is kept after one load, and a raised one lies above it.
                    const uint32_t chosen = vertex_count[j];
                    const uint32_t q = o.q < o.vertex_count ? o.q : o.vertex_count;
                    if (chosen >= q && chosen <= o.vertex_count && e[chosen] <= allowed) return chosen;
                    const uint32_t first = chosen >= q && chosen < o.vertex_count ? chosen + 1 : q;
                    k = hint ? levelWithinErrorNear(e, first, o.vertex_count, allowed, hint[id])
                             : levelWithinError(e, first, o.vertex_count, allowed);
                } else {
                    k = hint ? levelWithinErrorNear(e, o.q, o.vertex_count, allowed, hint[id])
                             : levelWithinError(e, o.q, o.vertex_count, allowed);
                }
                if (hint) hint[id] = k;
                if (raise) k = levelOnRaiseGrid(k, o.vertex_count, raise_step);
            }
        }
        if (raise && vertex_count[j] >= k) return vertex_count[j];
        vertex_count[j] = k;
        triangle_count[j] = k > 0 ? maps[map_first[o.mesh] + k] : 0u;
        return k;
    }
};

struct Plus {
    OCC_HD uint64_t operator()(uint64_t a, uint64_t b) const { return a + b; }
};

// Each listed object's error-bounded level (ErrorLevel, replacing or raising), summed; one
// readback of the sum.
uint64_t errorLevels(const ErrorLevel& level, uint32_t count) {
    if (count == 0) return 0;
    const thrust::counting_iterator<uint32_t> first(0);
    const uint64_t sum = thrust::transform_reduce(onDevice(), first, first + count, level, uint64_t(0), Plus());
    countReadback(sizeof sum);
    return sum;
}

}  // namespace

uint64_t lodSelectByError(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                          const Camera& camera, float tau, float pet, DevicePtr<const float> visible_share,
                          DevicePtr<const uint64_t> map_first,
                          DevicePtr<const float> lod_error, DevicePtr<const float> scale,
                          DevicePtr<const float> error_offset, DevicePtr<const uint32_t> maps,
                          DevicePtr<uint32_t> vertex_count, DevicePtr<uint32_t> triangle_count,
                          DevicePtr<uint32_t> hint) {
    return errorLevels(ErrorLevel{raw(objects), raw(ids), camera, tau, pet, raw(visible_share), raw(map_first),
                                  raw(lod_error), raw(scale), raw(error_offset), raw(maps), raw(vertex_count),
                                  raw(triangle_count), raw(hint), false, 0.0f},
                       count);
}

uint64_t lodRaiseToErrorBound(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                              const Camera& camera, float tau, float pet, DevicePtr<const float> visible_share,
                              DevicePtr<const uint64_t> map_first, DevicePtr<const float> lod_error,
                              DevicePtr<const float> scale, DevicePtr<const float> error_offset,
                              DevicePtr<const uint32_t> maps, DevicePtr<uint32_t> vertex_count,
                              DevicePtr<uint32_t> triangle_count, DevicePtr<uint32_t> hint, float raise_step) {
    return errorLevels(ErrorLevel{raw(objects), raw(ids), camera, tau, pet, raw(visible_share), raw(map_first),
                                  raw(lod_error), raw(scale), raw(error_offset), raw(maps), raw(vertex_count),
                                  raw(triangle_count), raw(hint), true, raise_step},
                       count);
}

uint64_t lodSelect(DevicePtr<const ObjectInfo> object_memory, DevicePtr<const uint32_t> id_memory, uint32_t count,
                   const Camera& camera, const LodParams& params, DevicePtr<const uint64_t> map_first,
                   DevicePtr<const uint32_t> maps, DevicePtr<uint32_t> vertex_count,
                   DevicePtr<uint32_t> triangle_count, DeviceArray<float>& share_memory) {
    if (count == 0) return 0;
    const ObjectInfo* const objects = raw(object_memory);
    const uint32_t* const ids = raw(id_memory);
    const thrust::counting_iterator<uint32_t> first(0);
    share_memory.growTo(count);
    float* const shares = raw(share_memory.ptr());

    const float exponent = (params.alpha - 1.0f) / params.alpha;
    thrust::transform(onDevice(), first, first + count, shares, LogShare{objects, ids, camera, exponent, params.pet, raw(params.visible_share)});
    const float max_log = thrust::reduce(onDevice(), shares, shares + count, -INFINITY, Maximum());
    countReadback(sizeof max_log);
    thrust::transform(onDevice(), shares, shares + count, shares, NormalizeShare{max_log});

    const Totals totals = thrust::transform_reduce(onDevice(), first, first + count, TotalsOf{objects, ids, shares},
                                                   Totals{0, 0, 0.0, 0.0}, AddTotals());
    countReadback(sizeof totals);
    const auto evaluate = [&](double lambda) {
        countReadback(sizeof(Evaluation));
        return thrust::transform_reduce(onDevice(), first, first + count, EvaluateAt{objects, ids, shares, lambda},
                                        Evaluation{0.0, 0.0, 0}, AddEvaluations());
    };

    const double lambda = solveLambda(evaluate, totals, params.budget);
    thrust::for_each_n(onDevice(), first, count,
                       WriteCounts{objects, ids, shares, raw(map_first), raw(maps), lambda, raw(vertex_count),
                                   raw(triangle_count)});
    return evaluate(lambda).rounded_sum;
}

}  // namespace occ::k
