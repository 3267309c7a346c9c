/**
 * The plugins of the generic Affordance Template SysRep ({@code sysrep/affordance_templates.yaml},
 * Fig. 1 of the paper): {@link caretaker.pax.at.AtCommandPlugin} maps its six commands onto the AT
 * server's services, {@link caretaker.pax.at.AtTelemetryPlugin} reads its six telemetry items from
 * the server's status topic. One SysRep serves every template and every robot; only the binding
 * (rosbridge URL, namespace) differs.
 */
package caretaker.pax.at;
