package caretaker.pax;

import java.time.Instant;

/**
 * The current value of a telemetry item.
 *
 * @param value the value as its SysRep type's Java type (String, Boolean, Long, Double), or null
 *     when none has been received yet
 * @param timestamp when the value was valid (the source's stamp if it has one, else when it
 *     arrived), or null when none has been received
 * @param stale whether the value is too old to trust (no update within the plugin's limit, or
 *     none received yet)
 */
public record TelemetryValue(Object value, Instant timestamp, boolean stale) {
    /** @return the value of an item that has never been received */
    public static TelemetryValue unknown() {
        return new TelemetryValue(null, null, true);
    }

    /** @return the same value marked stale */
    public TelemetryValue asStale() {
        return stale ? this : new TelemetryValue(value, timestamp, true);
    }
}
