// Trimmed mean of the last 5 samples of one input (PROTOCOL.md, "Timing"):
// the smallest and the largest are dropped, the middle 3 averaged. A single
// outlier never reaches the output (thesis 5.4: "averaged and filtered for
// outliers"). No Arduino dependency: the host tests compile it too.
#ifndef WHEXAR_SENSOR_FILTER_H
#define WHEXAR_SENSOR_FILTER_H

#include <stdint.h>

class TrimmedMean5 {
public:
    static const uint8_t kWindow = 5;

    TrimmedMean5();

    // Adds a sample (a 10-bit ADC count). The first one fills the whole
    // window, so the output is valid from the first sample on.
    void push(uint16_t sample);

    // Mean of the middle 3 of the last 5 samples, rounded to nearest:
    // (s + 1) / 3 for their sum s. 0 before the first sample.
    uint16_t value() const;

private:
    uint16_t window_[kWindow];
    uint8_t next_;     // slot the next sample overwrites
    bool primed_;      // false until the first sample
};

#endif
