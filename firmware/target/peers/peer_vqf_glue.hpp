/*
 * peer_vqf_glue.hpp - peers.h over one of VQF's filter classes (VQF or BasicVQF, vqf source
 * distribution, C++), single precision, its default parameters; the online update
 * update(gyr, acc, mag) and the 9D quaternion.
 */
#ifndef PEER_VQF_GLUE_HPP
#define PEER_VQF_GLUE_HPP

#include <new>

#include "peers.h"

template <class Filter> struct PeerVqfGlue {
    // Static storage, constructed in place: no heap, no static constructor.
    alignas(Filter) static unsigned char storage[sizeof(Filter)];
    static Filter *filter;

    static void init(float dt_s) { filter = new (storage) Filter(dt_s); }
    static void step(const float gyro_rad_s[3], const float accel_m_s2[3], const float mag_ut[3])
    {
        filter->update(gyro_rad_s, accel_m_s2, mag_ut);
    }
    static void quaternion(float q[4]) { filter->getQuat9D(q); }
    static constexpr peer_t descriptor(const char *name) { return {name, init, step, quaternion, sizeof(Filter)}; }
};

template <class Filter> alignas(Filter) unsigned char PeerVqfGlue<Filter>::storage[sizeof(Filter)];
template <class Filter> Filter *PeerVqfGlue<Filter>::filter = nullptr;

#endif /* PEER_VQF_GLUE_HPP */
