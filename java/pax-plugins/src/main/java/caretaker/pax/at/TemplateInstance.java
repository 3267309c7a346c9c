package caretaker.pax.at;

/**
 * A running Affordance Template instance, written {@code type:id} (e.g. {@code cdra_filter:0}).
 *
 * @param type the template type
 * @param id the instance number (the AT messages' {@code uint8 id})
 */
public record TemplateInstance(String type, int id) {
    /** Checks the id fits the AT messages' uint8. */
    public TemplateInstance {
        if (id < 0 || id > 255) {
            throw new IllegalArgumentException("template instance id must be within 0..255, got " + id);
        }
    }

    /**
     * @param text {@code type:id}
     * @return the instance, or null if {@code text} has no {@code :id} part (it names a type)
     * @throws IllegalArgumentException the id part is not a number within 0..255
     */
    public static TemplateInstance parse(String text) {
        int colon = text.lastIndexOf(':');
        if (colon < 0) {
            return null;
        }
        String number = text.substring(colon + 1);
        try {
            return new TemplateInstance(text.substring(0, colon), Integer.parseInt(number));
        } catch (NumberFormatException e) {
            throw new IllegalArgumentException("'" + text + "' is neither a template type nor an instance"
                    + " 'type:id' with a number id", e);
        }
    }

    /**
     * @param text what a server reported as an instance
     * @return the instance, or null if {@code text} is not a valid {@code type:id}
     */
    public static TemplateInstance parseOrNull(String text) {
        try {
            return parse(text);
        } catch (IllegalArgumentException e) {
            return null;
        }
    }

    /** @return {@code type:id} */
    @Override
    public String toString() {
        return type + ":" + id;
    }
}
