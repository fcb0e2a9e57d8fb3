/*
 * peers.h - one C interface over the peers' filters, for measuring them next to attekf on
 * the same boards with the same samples (scripts/bench_firmware.py --peers,
 * docs/performance.md "Peers on the same boards").
 *
 * The peers' sources are not part of this repository: the benchmark downloads them (Fusion
 * from the imufusion source distribution, VQF and BasicVQF from the vqf one, versions and
 * SHA-256 pinned in scripts/bench_peers.py) into the build tree and builds them with the flags of
 * the board. This glue calls their public APIs only; VQF in single precision
 * (VQF_SINGLE_PRECISION), each with its authors' default parameters (Fusion: the settings
 * of x-io's examples, as in attekf bench).
 */
#ifndef PEERS_H
#define PEERS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *name;
    /* (Re)initialises the filter for a sample period dt, s. */
    void (*init)(float dt_s);
    /* One full update: gyroscope rad/s, accelerometer m/s^2 (specific force), magnetometer
     * (any unit, uT here); each peer converts to its own units. */
    void (*step)(const float gyro_rad_s[3], const float accel_m_s2[3], const float mag_ut[3]);
    /* Orientation body -> earth (earth z up), w x y z. */
    void (*quaternion)(float q[4]);
    /* Bytes of the filter object (its whole state). */
    size_t state_bytes;
} peer_t;

extern const peer_t peer_fusion;
extern const peer_t peer_vqf;
extern const peer_t peer_basicvqf;

#ifdef __cplusplus
}
#endif

#endif /* PEERS_H */
