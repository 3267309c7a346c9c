/**
 * The System Representation (SysRep) model and its loader: the commands and telemetry a procedure
 * may name (docs/architecture.md, interface 1). Validation and every error message match the Python
 * loader {@code procedure_language.sysrep}; both are checked against {@code tests/fixtures/sysrep}.
 */
package caretaker.sysrep;
