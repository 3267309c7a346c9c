package caretaker.rosbridge;

import com.google.gson.JsonObject;
import java.nio.charset.StandardCharsets;
import java.security.GeneralSecurityException;
import java.security.SecureRandom;
import java.time.Duration;
import java.time.Instant;
import java.util.HexFormat;
import javax.crypto.Mac;
import javax.crypto.spec.SecretKeySpec;

/**
 * The {@code auth} message a {@link Ros} connection sends first, on every (re)connect, to a
 * bridge that requires authentication (docs/rosbridge.md, "Security"). Either an HMAC over
 * rosauth's fields with a shared secret, which never crosses the link, or a bearer token (send
 * it over {@code wss://} only). {@link #toString()} never shows the secret.
 */
public sealed interface RosAuth {
    /**
     * @param dest the server's host, as the MAC's {@code dest}
     * @param now the client's clock
     * @param random the source of the per-connection {@code rand}
     * @return the complete {@code auth} message
     */
    JsonObject message(String dest, Instant now, SecureRandom random);

    /**
     * @param secret the bridge's shared secret
     * @return HMAC authentication as client {@code caretaker-pax}, level {@code user}, valid 60 s
     */
    static RosAuth hmac(String secret) {
        return hmac(secret, Duration.ofSeconds(60));
    }

    /**
     * @param secret the bridge's shared secret
     * @param validity how long a login stays valid from its signing (across a long link:
     *     {@link LinkOptions#loginValidity()}, or it expires on the way)
     * @return HMAC authentication as client {@code caretaker-pax}, level {@code user}
     */
    static RosAuth hmac(String secret, Duration validity) {
        return new Hmac(secret, "caretaker-pax", "user", validity);
    }

    /**
     * @param token the bridge's shared secret, sent as it is
     * @return bearer-token authentication
     */
    static RosAuth token(String token) {
        return new Token(token);
    }

    /**
     * {@code mac = hex(HMAC-SHA256(secret, client + dest + rand + t + level + end))}, {@code t} the
     * client's Unix time and {@code end} the end of validity, both in whole seconds.
     *
     * @param secret the shared secret
     * @param client who connects (rosauth's client field)
     * @param level the access level asked for
     * @param validity how long the message stays valid
     */
    record Hmac(String secret, String client, String level, Duration validity) implements RosAuth {
        /** Checks the secret is not empty. */
        public Hmac {
            if (secret == null || secret.isEmpty()) {
                throw new IllegalArgumentException("the shared secret is empty");
            }
        }

        @Override
        public JsonObject message(String dest, Instant now, SecureRandom random) {
            byte[] nonce = new byte[16];
            random.nextBytes(nonce);
            String rand = HexFormat.of().formatHex(nonce);
            long t = now.getEpochSecond();
            long end = t + validity.toSeconds();
            JsonObject auth = new JsonObject();
            auth.addProperty(Protocol.FIELD_OP, Protocol.OP_AUTH);
            auth.addProperty(Protocol.FIELD_MAC, mac(secret, client + dest + rand + t + level + end));
            auth.addProperty(Protocol.FIELD_CLIENT, client);
            auth.addProperty(Protocol.FIELD_DEST, dest);
            auth.addProperty(Protocol.FIELD_RAND, rand);
            auth.addProperty(Protocol.FIELD_T, t);
            auth.addProperty(Protocol.FIELD_LEVEL, level);
            auth.addProperty(Protocol.FIELD_END, end);
            return auth;
        }

        /**
         * @param key the shared secret
         * @param text the concatenated fields
         * @return lower-case hex of HMAC-SHA256
         */
        static String mac(String key, String text) {
            try {
                Mac hmac = Mac.getInstance("HmacSHA256");
                hmac.init(new SecretKeySpec(key.getBytes(StandardCharsets.UTF_8), "HmacSHA256"));
                return HexFormat.of().formatHex(hmac.doFinal(text.getBytes(StandardCharsets.UTF_8)));
            } catch (GeneralSecurityException e) {
                throw new IllegalStateException("HmacSHA256 is missing from this JDK", e);
            }
        }

        @Override
        public String toString() {
            return "Hmac[client=" + client + ", level=" + level + ", validity=" + validity + ", secret hidden]";
        }
    }

    /**
     * @param token the shared secret, sent as {@code {"op":"auth","token":...}}
     */
    record Token(String token) implements RosAuth {
        /** Checks the token is not empty. */
        public Token {
            if (token == null || token.isEmpty()) {
                throw new IllegalArgumentException("the token is empty");
            }
        }

        @Override
        public JsonObject message(String dest, Instant now, SecureRandom random) {
            JsonObject auth = new JsonObject();
            auth.addProperty(Protocol.FIELD_OP, Protocol.OP_AUTH);
            auth.addProperty(Protocol.FIELD_TOKEN, token);
            return auth;
        }

        @Override
        public String toString() {
            return "Token[hidden]";
        }
    }
}
