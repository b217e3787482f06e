// A span of explicit steps run without a host round-trip between them (Runner::advance_span).
// The rules that pick each step's size and end a span are written once here, for the host
// loop (driver, CPU twin) and for the CUDA backend, which applies them on the device so an
// adaptive span needs no host either. On the device the arithmetic is rounded exactly as on
// the host (no fused multiply-add), so both make the same decisions from the same numbers.
#pragma once

#include <cstdint>

#include <granflow/constitutive/config.hpp>

namespace granflow::mpm {

// Size of a step from t: dt, shortened to land exactly on t_land when t + dt would reach it
// or pass it, or stop within 1e-9 dt short of it (the driver's landing on stage ends, samples
// and frames).
GF_HDI double span_step_size(double t, double dt, double t_land) {
#ifdef __CUDA_ARCH__
  const bool land = __dadd_rn(t, dt) > __dsub_rn(t_land, __dmul_rn(1e-9, dt)) && t_land > t;
  return land ? __dsub_rn(t_land, t) : dt;
#else
  if (t + dt > t_land - 1e-9 * dt && t_land > t) return t_land - t;
  return dt;
#endif
}

// Adaptive step: the smallest stable step of the particles, capped by dt_max (std::min order:
// a NaN limit gives the limit, as the host loop did).
GF_HDI double span_next_dt(double limit, double dt_max) { return dt_max < limit ? dt_max : limit; }

// A next step that the stable limit planned below dt_max counts as shortened (SpanResult's
// shortened and dt_min).
template <class Count>
GF_HDI void span_count_shortened(double dt, double dt_max, Count& shortened, double& dt_min) {
  if (dt < dt_max) {
    shortened += 1;
    dt_min = dt < dt_min ? dt : dt_min;
  }
}

// A span ends after the first step whose end time reaches t_until (or after max_steps steps,
// or on a failed step).
GF_HDI bool span_reached(double t, double t_until) { return t >= t_until; }

// Smallest stable step of a span kept as the bits of a non-negative double: their unsigned
// order is the order of the values, so one integer atomicMin reduces it on the device.
GF_HDI std::uint64_t dt_limit_bits(double v) {
#ifdef __CUDA_ARCH__
  return static_cast<std::uint64_t>(__double_as_longlong(v));
#else
  std::uint64_t b;
  __builtin_memcpy(&b, &v, sizeof b);
  return b;
#endif
}
GF_HDI double dt_limit_value(std::uint64_t b) {
#ifdef __CUDA_ARCH__
  return __longlong_as_double(static_cast<long long>(b));
#else
  double v;
  __builtin_memcpy(&v, &b, sizeof v);
  return v;
#endif
}

// First bad particle of a span as one word: original particle index in the high half, its
// status in the low half. The smallest word is the smallest index (the host loop's choice).
GF_HDI std::uint64_t pack_bad(std::uint32_t original_index, std::uint32_t status) {
  return (static_cast<std::uint64_t>(original_index) << 32) | status;
}
inline constexpr std::uint64_t kNoBadParticle = ~std::uint64_t(0);

}  // namespace granflow::mpm
