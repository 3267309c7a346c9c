/**
 * The PAX plugin API (docs/architecture.md, interface 5): a {@link caretaker.pax.CommandPlugin} executes
 * SysRep commands with typed, validated arguments and returns a {@link caretaker.pax.CommandResult};
 * a {@link caretaker.pax.TelemetryPlugin} reports each telemetry item's
 * {@link caretaker.pax.TelemetryValue} and notifies {@link caretaker.pax.TelemetryListener}s.
 */
package caretaker.pax;
