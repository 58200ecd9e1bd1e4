#pragma once
// pybind11 conversions for the GLM types of fvr::core's interface (core::Vec3 is glm::dvec3,
// Volume::direction a glm::dmat3): Python sees them exactly as it saw std::array<double, 3> and
// std::array<std::array<double, 3>, 3> before, through pybind11's own std::array caster. Out: a
// list of 3 floats (a matrix: a list of its 3 columns, direction[a] being index axis a). In: any
// sequence of 3 numbers (a matrix: of 3 such sequences); anything else does not match.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace pybind11::detail {

template <>
struct type_caster<glm::dvec3> {
    using Array = std::array<double, 3>;
    PYBIND11_TYPE_CASTER(glm::dvec3, make_caster<Array>::name);

    bool load(handle src, bool convert) {
        make_caster<Array> inner;
        if (!inner.load(src, convert)) return false;
        const Array& a = cast_op<const Array&>(inner);
        value = glm::dvec3(a[0], a[1], a[2]);
        return true;
    }
    static handle cast(const glm::dvec3& v, return_value_policy policy, handle parent) {
        return make_caster<Array>::cast(Array{v.x, v.y, v.z}, policy, parent);
    }
};

template <>
struct type_caster<glm::dmat3> {
    using Array = std::array<std::array<double, 3>, 3>;
    PYBIND11_TYPE_CASTER(glm::dmat3, make_caster<Array>::name);

    bool load(handle src, bool convert) {
        make_caster<Array> inner;
        if (!inner.load(src, convert)) return false;
        const Array& a = cast_op<const Array&>(inner);
        for (int c = 0; c < 3; ++c)
            value[c] = glm::dvec3(a[std::size_t(c)][0], a[std::size_t(c)][1], a[std::size_t(c)][2]);
        return true;
    }
    static handle cast(const glm::dmat3& m, return_value_policy policy, handle parent) {
        Array a;
        for (int c = 0; c < 3; ++c) a[std::size_t(c)] = {m[c].x, m[c].y, m[c].z};
        return make_caster<Array>::cast(a, policy, parent);
    }
};

} // namespace pybind11::detail
