package caretaker.rosbridge;

import java.time.Duration;

/** Formats durations the way error messages show them (seconds, up to millisecond precision). */
final class Durations {
    private Durations() {
    }

    static String seconds(Duration duration) {
        double seconds = duration.toMillis() / 1000.0;
        return seconds == Math.rint(seconds) ? Long.toString((long) seconds) : Double.toString(seconds);
    }
}
