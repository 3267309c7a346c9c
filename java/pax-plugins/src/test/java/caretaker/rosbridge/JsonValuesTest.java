package caretaker.rosbridge;

import static org.junit.jupiter.api.Assertions.assertEquals;
import static org.junit.jupiter.api.Assertions.assertNull;

import com.google.gson.JsonNull;
import com.google.gson.JsonParser;
import org.junit.jupiter.api.Test;

/** JSON fields become the Java values PAX checks against SysRep types. */
class JsonValuesTest {
    private static Object plain(String json) {
        return JsonValues.plain(JsonParser.parseString(json));
    }

    @Test
    void primitivesBecomeBooleanLongDoubleOrString() {
        assertEquals(Boolean.TRUE, plain("true"));
        assertEquals(3L, plain("3"));
        assertEquals(3L, plain("3.0"));
        assertEquals(0.25, plain("0.25"));
        assertEquals(1e16, plain("1e16"));
        assertEquals("SUCCEEDED", plain("\"SUCCEEDED\""));
    }

    @Test
    void missingNullAndStructuredFields() {
        assertNull(JsonValues.plain(null));
        assertNull(JsonValues.plain(JsonNull.INSTANCE));
        assertEquals("[1,2]", plain("[1, 2]"));
        assertEquals("{\"a\":1}", plain("{\"a\": 1}"));
    }
}
