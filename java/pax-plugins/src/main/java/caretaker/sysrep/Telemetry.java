package caretaker.sysrep;

import java.util.List;

/**
 * A telemetry item of a system: what a verify or wait instruction reads.
 *
 * @param id the item id
 * @param label the human-readable name
 * @param type the value type
 * @param units units for display, or null
 * @param min least expected value, or null
 * @param max largest expected value, or null
 * @param allowed the expected values (the SysRep's {@code enum}), or null
 * @param description free text, or null
 * @param limits the item's limits (procedures' monitors read them), or null
 * @param line where the item starts in its file (1-based), 0 if not from a file
 */
public record Telemetry(String id, String label, ValueType type, String units, Number min, Number max,
        List<Object> allowed, String description, Limits limits, int line) {
    /** Copies the allowed values so the record stays immutable. */
    public Telemetry {
        allowed = allowed == null ? null : List.copyOf(allowed);
    }
}
