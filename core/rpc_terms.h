// The 20 RPC00B cubic monomials, shared by the model (core/rpc.cpp) and the
// fitter (core/rpc_fit.cpp). Internal to core.
#pragma once

#include <array>

namespace skyfall::rpc_terms {

using Terms = std::array<double, 20>;

// Monomials of normalized (L = lon, P = lat, H = height) in RPC00B order:
// 1 L P H LP LH PH L2 P2 H2 PLH L3 LP2 LH2 L2P P3 PH2 L2H P2H H3.
inline Terms Monomials(double L, double P, double H) {
  return {1.0,       L,         P,         H,         L * P,     L * H,     P * H,
          L * L,     P * P,     H * H,     P * L * H, L * L * L, L * P * P, L * H * H,
          L * L * P, P * P * P, P * H * H, L * L * H, P * P * H, H * H * H};
}

inline double Dot(const Terms& coefficients, const Terms& monomials) {
  double s = 0.0;
  for (int i = 0; i < 20; ++i) s += coefficients[i] * monomials[i];
  return s;
}

}  // namespace skyfall::rpc_terms
