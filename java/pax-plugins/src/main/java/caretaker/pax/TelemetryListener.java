package caretaker.pax;

/** Hears about telemetry changes (value or staleness). */
@FunctionalInterface
public interface TelemetryListener {
    /**
     * Called on the plugin's thread after the value changed; must return quickly.
     *
     * @param sysrepId the SysRep of the item
     * @param itemId the telemetry item
     * @param value its new value
     */
    void telemetryChanged(String sysrepId, String itemId, TelemetryValue value);
}
