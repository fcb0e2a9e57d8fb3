/*
 * peer_vqf.cpp - VQF, the full filter (rest and motion bias estimation, magnetic disturbance
 * rejection), behind peers.h (peer_vqf_glue.hpp).
 */
#include "peer_vqf_glue.hpp"
#include "vqf.hpp"

extern "C" const peer_t peer_vqf = PeerVqfGlue<VQF>::descriptor("VQF");
