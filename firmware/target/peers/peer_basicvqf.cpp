/*
 * peer_basicvqf.cpp - BasicVQF (the basic variant: no bias estimation, no magnetic
 * disturbance rejection; vqf source distribution, C++) behind peers.h, single precision,
 * its default parameters: BasicVQF::update(gyr, acc, mag).
 */
#include <new>

#include "peers.h"
#include "basicvqf.hpp"

namespace {
// Static storage, constructed in place: no heap, no static constructor.
alignas(BasicVQF) unsigned char storage[sizeof(BasicVQF)];
BasicVQF *filter = nullptr;

void basicvqf_init(float dt_s)
{
    filter = new (storage) BasicVQF(dt_s);
}

void basicvqf_step(const float gyro_rad_s[3], const float accel_m_s2[3], const float mag_ut[3])
{
    filter->update(gyro_rad_s, accel_m_s2, mag_ut);
}

void basicvqf_quaternion(float q[4])
{
    filter->getQuat9D(q);
}
} // namespace

extern "C" const peer_t peer_basicvqf = {"BasicVQF", basicvqf_init, basicvqf_step, basicvqf_quaternion, sizeof(BasicVQF)};
