/*
 * peer_vqf.cpp - VQF (full: rest and motion bias estimation, magnetic disturbance
 * rejection; vqf source distribution, C++) behind peers.h, single precision, its default
 * parameters: VQF::update(gyr, acc, mag), the online filter.
 */
#include <new>

#include "peers.h"
#include "vqf.hpp"

namespace {
// Static storage, constructed in place: no heap, no static constructor.
alignas(VQF) unsigned char storage[sizeof(VQF)];
VQF *filter = nullptr;

void vqf_init(float dt_s)
{
    filter = new (storage) VQF(dt_s);
}

void vqf_step(const float gyro_rad_s[3], const float accel_m_s2[3], const float mag_ut[3])
{
    filter->update(gyro_rad_s, accel_m_s2, mag_ut);
}

void vqf_quaternion(float q[4])
{
    filter->getQuat9D(q);
}
} // namespace

extern "C" const peer_t peer_vqf = {"VQF", vqf_init, vqf_step, vqf_quaternion, sizeof(VQF)};
