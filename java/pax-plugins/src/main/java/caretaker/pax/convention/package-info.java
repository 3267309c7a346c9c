/**
 * Serves a simple SysRep by naming convention, so a plain system needs a YAML file and a binding
 * entry but no Java code. See {@link caretaker.pax.convention.RosConventionPlugin} for the rules.
 */
package caretaker.pax.convention;
