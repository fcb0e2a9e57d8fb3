/*
 * peer_footprint.c - the smallest program that uses one peer's filter (PEER, a peers.h
 * descriptor) the way firmware would, like footprint.c for attekf: its link map gives the
 * peer's flash and RAM with what it pulls in (scripts/bench_firmware.py --peers).
 */
#include "peers.h"

volatile float fp_in[9] = {0.01f, 0.0f, 0.0f, 0.0f, 0.0f, 9.81f, 20.0f, 0.0f, -40.0f};
volatile float fp_out[4];

int main(void)
{
    float g[3], a[3], m[3], q[4];
    int i, k;
    PEER.init(0.01f);
    for (k = 0; k < 100; ++k) {
        for (i = 0; i < 3; ++i) {
            g[i] = fp_in[i];
            a[i] = fp_in[3 + i];
            m[i] = fp_in[6 + i];
        }
        PEER.step(g, a, m);
    }
    PEER.quaternion(q);
    for (i = 0; i < 4; ++i) {
        fp_out[i] = q[i];
    }
    return 0;
}
