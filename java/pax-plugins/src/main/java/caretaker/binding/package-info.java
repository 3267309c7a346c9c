/**
 * Bindings (docs/architecture.md, interface 3): which plugin serves which SysRep on which robot, over
 * which rosbridge, in which ROS namespace; and {@link caretaker.binding.PaxHost}, which loads a
 * binding and offers its SysReps' commands and telemetry — to Java directly, and to Python through
 * {@code pride.pax_host}.
 */
package caretaker.binding;
