package caretaker.rosbridge;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertFalse;
import static org.junit.jupiter.api.Assertions.assertTrue;

import java.time.Duration;
import java.time.Instant;
import org.junit.jupiter.api.Test;

/** The habitat clock estimate: skew found from the least-delayed message, late messages ignored. */
class HabitatClockTest {
    private static final Instant GROUND = Instant.parse("2026-11-23T12:00:00Z");
    /** The habitat's clock is 100 s behind the ground's. */
    private static final Duration SKEW = Duration.ofSeconds(100);

    /** A status sent at ground time {@code sentAt} s, arriving after {@code delay} s. */
    private static void observe(HabitatClock clock, double sentAt, double delay) {
        Instant sent = GROUND.plusMillis(Math.round(sentAt * 1000));
        Instant received = sent.plusMillis(Math.round(delay * 1000));
        clock.observe(sent.minus(SKEW), received, Duration.between(GROUND, received).toNanos());
    }

    @Test
    void theSkewIsFoundFromTheLeastDelayedStatusAndStallsAreIgnored() {
        HabitatClock clock = new HabitatClock(Duration.ofMillis(1300));
        assertFalse(clock.known());
        assertEquals(GROUND, clock.toGround(GROUND), "before any status a stamp is taken as it is");
        observe(clock, 0.0, 4.1); // stalled behind a lost segment
        observe(clock, 0.2, 1.3);
        observe(clock, 0.4, 1.5); // jitter
        observe(clock, 0.6, 9.0); // held by an outage
        assertTrue(clock.known());
        assertEquals(SKEW, clock.offset());
        Instant stamp = GROUND.minus(SKEW);
        assertEquals(GROUND, clock.toGround(stamp), "a habitat stamp lands on the ground clock");
    }

    @Test
    void aSampleLeavesTheWindowSoAStepOfAClockIsFollowed() {
        HabitatClock clock = new HabitatClock(Duration.ZERO, Duration.ofSeconds(10));
        observe(clock, 0.0, 0.0);
        assertEquals(SKEW, clock.offset());
        // the habitat's clock is stepped 5 s forward: samples are 5 s smaller from now on
        for (int second = 1; second <= 12; second++) {
            Instant sent = GROUND.plusSeconds(second);
            clock.observe(sent.minus(SKEW).plusSeconds(5), sent, Duration.ofSeconds(second).toNanos());
        }
        assertEquals(SKEW.minusSeconds(5), clock.offset());
    }

    @Test
    void aStampIsNeverPlacedAfterItsArrivalEvenWhenTheLinkIsSlowerThanStated() {
        HabitatClock clock = new HabitatClock(Duration.ZERO); // the binding says loopback
        observe(clock, 0.0, 1.3); // the link is 1.3 s
        observe(clock, 0.5, 2.0);
        assertEquals(GROUND.plusMillis(1300), clock.toGround(GROUND.minus(SKEW)), "younger by the error, 1.3 s");
        assertEquals(GROUND.plusMillis(1800), clock.toGround(GROUND.plusMillis(500).minus(SKEW)),
                "before its arrival at 2.5 s");
    }
}
