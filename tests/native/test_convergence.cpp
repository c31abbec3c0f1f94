#include "render/convergence.h"

#include <gtest/gtest.h>

#include <cmath>

using coherent::predicted_seconds_to_error;

TEST(Convergence, HalvingErrorTakesFourTimesTheTime) {
    // err 2 % at 10 s -> 1 % needs 4x the samples, so 40 s in all.
    EXPECT_DOUBLE_EQ(predicted_seconds_to_error(10.0, 0.02, 0.01), 40.0);
}

TEST(Convergence, AgreesWithSimulatedOneOverSqrtDecay) {
    // Independent oracle: a synthetic error curve e(t) = c / sqrt(t); the
    // prediction from any point must hit the time where the curve meets the target.
    const double c = 0.3;
    for (double t_now : {0.5, 3.0, 17.0}) {
        const double e_now = c / std::sqrt(t_now);
        for (double target : {0.01, 0.005, 0.2}) {
            const double expected = (c / target) * (c / target);
            EXPECT_NEAR(predicted_seconds_to_error(t_now, e_now, target), expected, 1e-9 * expected);
        }
    }
}

TEST(Convergence, TargetAlreadyReachedGivesEarlierTime) {
    EXPECT_LE(predicted_seconds_to_error(10.0, 0.005, 0.01), 10.0);
}

TEST(Convergence, NoPredictionWithoutEstimateOrTarget) {
    EXPECT_LT(predicted_seconds_to_error(10.0, -1.0, 0.01), 0.0);  // estimate unknown
    EXPECT_LT(predicted_seconds_to_error(10.0, 0.02, 0.0), 0.0);   // no target
    EXPECT_LT(predicted_seconds_to_error(10.0, NAN, 0.01), 0.0);
    EXPECT_LT(predicted_seconds_to_error(INFINITY, 0.02, 0.01), 0.0);
    EXPECT_LT(predicted_seconds_to_error(10.0, 1e300, 1e-300), 0.0);  // overflow -> no prediction
}
