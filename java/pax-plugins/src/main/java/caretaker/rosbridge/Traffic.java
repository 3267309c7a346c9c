package caretaker.rosbridge;

import java.net.URI;

/**
 * What one rosbridge connection carried, counted by the client across reconnects: WebSocket
 * frames each way, their payload and frame headers (a client's frames carry a 4-byte mask).
 * TLS records and TCP/IP headers are not included; a link emulator or the network counts those.
 *
 * @param rosbridge the server's URI
 * @param bytesUp bytes sent to the server (ground → habitat)
 * @param bytesDown bytes received from it (habitat → ground)
 * @param messagesUp messages sent (text messages, pings, pongs and closes)
 * @param messagesDown messages received
 */
public record Traffic(URI rosbridge, long bytesUp, long bytesDown, long messagesUp, long messagesDown) {
    /**
     * @param payload bytes of a frame's payload
     * @param masked whether the frame is masked (every client frame is)
     * @return the frame's size on the WebSocket: header, extended length, mask, payload
     */
    public static long frameSize(long payload, boolean masked) {
        long header = payload < 126 ? 2 : payload < 65536 ? 4 : 10;
        return header + (masked ? 4 : 0) + payload;
    }

    /**
     * @param text a text message
     * @return its length in UTF-8, without encoding it
     */
    public static long utf8Length(CharSequence text) {
        long length = 0;
        for (int i = 0; i < text.length(); i++) {
            char c = text.charAt(i);
            if (c < 0x80) {
                length += 1;
            } else if (c < 0x800) {
                length += 2;
            } else if (Character.isHighSurrogate(c) && i + 1 < text.length()
                    && Character.isLowSurrogate(text.charAt(i + 1))) {
                length += 4;
                i++;
            } else {
                length += 3;
            }
        }
        return length;
    }
}
