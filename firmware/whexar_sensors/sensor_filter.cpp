#include "sensor_filter.h"

TrimmedMean5::TrimmedMean5() : next_(0), primed_(false) {
    for (uint8_t i = 0; i < kWindow; ++i) window_[i] = 0;
}

void TrimmedMean5::push(uint16_t sample) {
    if (!primed_) {
        for (uint8_t i = 0; i < kWindow; ++i) window_[i] = sample;
        primed_ = true;
        next_ = 0;
        return;
    }
    window_[next_] = sample;
    next_ = (uint8_t)(next_ == kWindow - 1 ? 0 : next_ + 1);
}

uint16_t TrimmedMean5::value() const {
    // 5 * 1023 fits in 16 bits; any 16-bit sample fits in 32.
    uint32_t sum = 0;
    uint16_t lo = window_[0], hi = window_[0];
    for (uint8_t i = 0; i < kWindow; ++i) {
        uint16_t v = window_[i];
        sum += v;
        if (v < lo) lo = v;
        if (v > hi) hi = v;
    }
    return (uint16_t)((sum - lo - hi + 1) / 3);
}
