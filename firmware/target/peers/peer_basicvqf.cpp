/*
 * peer_basicvqf.cpp - BasicVQF (no bias estimation, no magnetic disturbance rejection)
 * behind peers.h (peer_vqf_glue.hpp).
 */
#include "basicvqf.hpp"
#include "peer_vqf_glue.hpp"

extern "C" const peer_t peer_basicvqf = PeerVqfGlue<BasicVQF>::descriptor("BasicVQF");
