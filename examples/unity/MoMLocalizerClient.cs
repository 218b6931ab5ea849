// MoM Localizer client for Unity: one GameObject per tracked person, moved from the daemon's
// WebSocket stream (WS /v1/stream, snapshot schema version 1). A single drop-in file: copy it into
// Assets/, it needs nothing beyond Unity's own assemblies (.NET Standard 2.1 / .NET 4.x profile).
//
// Usage: add this component to any GameObject in the scene, set `Url` (and `Token` if the daemon
// has one), optionally assign a `PersonPrefab` (a capsule is created otherwise). Floor coordinates
// (x, y) in metres map to Unity (x, 0, y) * Scale + Origin (Unity is y-up, 1 unit = 1 metre).
//
// Design:
// - The socket runs on a background task (System.Net.WebSockets.ClientWebSocket); Unity objects
//   may only be touched on the main thread, so the task stores only the newest snapshot (a
//   latest-value slot under a lock) and Update() applies it. A slow frame skips snapshots instead
//   of queueing them.
// - Reconnects with exponential back-off (0.5 s doubling to MaxBackoffSeconds, reset after a
//   successful connect). Close code 4401 (token missing or wrong) stops retrying: TokenRejected
//   turns true and an error is logged, because retrying with the same token cannot succeed.
// - Messages are parsed by the small JSON reader at the end of this file rather than JsonUtility,
//   so that the exact parsing code is the one the project's tests run (under Mono, outside Unity);
//   unknown keys are ignored, so newer daemons that add fields keep working. Fragments are
//   reassembled.
// - A person missing from the stream for DespawnSeconds is destroyed; motion is smoothed
//   (exponential approach at rate Smoothing, frame-rate independent).
//
// Not for WebGL builds (ClientWebSocket is unavailable there; use examples/web/momloc-client.js
// from a .jslib, or the OSC output).

using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;
using System.Net.WebSockets;
using System.Text;
using System.Threading;
using System.Threading.Tasks;
using UnityEngine;

public class MoMLocalizerClient : MonoBehaviour
{
    public const int TokenRejectedCloseCode = 4401;

    [Serializable]
    public class Person
    {
        public int id;
        public float x;
        public float y;
        public float vx;
        public float vy;
        public float confidence;
        public int[] cameras;
    }

    [Serializable]
    public class Snapshot
    {
        public int v;
        public long seq;
        public double t;
        public Person[] people;
    }

    [Tooltip("Daemon stream URL, e.g. ws://192.168.1.20:8765/v1/stream")]
    public string Url = "ws://127.0.0.1:8765/v1/stream";

    [Tooltip("API token (leave empty when the daemon has none)")]
    public string Token = "";

    [Tooltip("Spawned once per person id; a capsule when empty")]
    public GameObject PersonPrefab;

    public Vector3 Origin = Vector3.zero;
    public float Scale = 1f;

    [Tooltip("Position smoothing rate (1/s); 0 = jump to each new position")]
    public float Smoothing = 15f;

    public float DespawnSeconds = 2f;
    public float MaxBackoffSeconds = 10f;

    [Tooltip("Hide people below this confidence (coasting tracks fade towards 0)")]
    public float MinConfidence = 0f;

    /// <summary>True while the socket is open.</summary>
    public bool Connected { get; private set; }

    /// <summary>True once the daemon refused the token (no more retries until re-enabled).</summary>
    public bool TokenRejected { get; private set; }

    /// <summary>Connection attempts since OnEnable (connects and failures).</summary>
    public int Attempts { get; private set; }

    /// <summary>seq of the last snapshot applied in Update (restarts at 1 with the daemon).</summary>
    public long LastSeq { get; private set; }

    /// <summary>Capture time (unix seconds) of the last applied snapshot: latency = now - this.</summary>
    public double LastCaptureTime { get; private set; }

    /// <summary>The last connection problem, null while all is well.</summary>
    public string LastError { get; private set; }

    /// <summary>The live GameObject of each person id (read-only view, main thread).</summary>
    public IReadOnlyDictionary<int, GameObject> People { get { return _objects; } }

    private readonly object _lock = new object();
    private Snapshot _latest;
    private CancellationTokenSource _cancel;
    private readonly Dictionary<int, GameObject> _objects = new Dictionary<int, GameObject>();
    private readonly Dictionary<int, Vector3> _targets = new Dictionary<int, Vector3>();
    private readonly Dictionary<int, float> _lastSeen = new Dictionary<int, float>();

    private void OnEnable()
    {
        TokenRejected = false;
        Attempts = 0;
        _cancel = new CancellationTokenSource();
        var token = _cancel.Token;
        string url = Url, apiToken = Token;  // read on the main thread
        Task.Run(() => ReceiveLoop(url, apiToken, token));
    }

    private void OnDisable()
    {
        if (_cancel != null)
        {
            _cancel.Cancel();
            _cancel.Dispose();
            _cancel = null;
        }
        Connected = false;
    }

    private void OnDestroy()
    {
        foreach (var go in _objects.Values)
        {
            if (go != null) Destroy(go);
        }
        _objects.Clear();
    }

    // Background task: connect, read messages, keep only the newest snapshot; reconnect on error.
    private async Task ReceiveLoop(string url, string apiToken, CancellationToken cancel)
    {
        double delay = 0.5;
        var buffer = new byte[64 * 1024];
        while (!cancel.IsCancellationRequested)
        {
            using (var socket = new ClientWebSocket())
            {
                try
                {
                    if (!string.IsNullOrEmpty(apiToken))
                        socket.Options.SetRequestHeader("Authorization", "Bearer " + apiToken);
                    socket.Options.KeepAliveInterval = TimeSpan.FromSeconds(10);
                    Attempts++;
                    await socket.ConnectAsync(new Uri(url), cancel);
                    Connected = true;
                    LastError = null;
                    delay = 0.5;
                    Debug.Log("MoMLocalizerClient: connected to " + url);
                    if (await ReadMessages(socket, buffer, cancel))
                    {
                        TokenRejected = true;
                        Connected = false;
                        LastError = "the daemon rejected the token";
                        Debug.LogError("MoMLocalizerClient: the daemon rejected the token (close code 4401); set Token and re-enable the component");
                        return;
                    }
                    LastError = "connection closed by the daemon";
                    Debug.LogWarning("MoMLocalizerClient: " + LastError + "; reconnecting");
                }
                catch (OperationCanceledException)
                {
                    return;
                }
                catch (Exception error)
                {
                    LastError = error.Message;
                    Debug.LogWarning("MoMLocalizerClient: " + error.Message + "; retrying in " + delay.ToString("0.0", CultureInfo.InvariantCulture) + " s");
                }
            }
            Connected = false;
            try
            {
                await Task.Delay(TimeSpan.FromSeconds(delay), cancel);
            }
            catch (OperationCanceledException)
            {
                return;
            }
            delay = Math.Min(delay * 2, MaxBackoffSeconds);
        }
    }

    // Reads until the socket closes; true when the daemon closed it because of the token.
    private async Task<bool> ReadMessages(ClientWebSocket socket, byte[] buffer, CancellationToken cancel)
    {
        using (var message = new MemoryStream())
        {
            while (socket.State == WebSocketState.Open && !cancel.IsCancellationRequested)
            {
                var result = await socket.ReceiveAsync(new ArraySegment<byte>(buffer), cancel);
                if (result.MessageType == WebSocketMessageType.Close)
                {
                    bool rejected = (int?)result.CloseStatus == TokenRejectedCloseCode;
                    try
                    {
                        await socket.CloseOutputAsync(WebSocketCloseStatus.NormalClosure, "", cancel);
                    }
                    catch (WebSocketException) { }
                    return rejected;
                }
                message.Write(buffer, 0, result.Count);
                if (!result.EndOfMessage) continue;
                var text = Encoding.UTF8.GetString(message.GetBuffer(), 0, (int)message.Length);
                message.SetLength(0);
                Snapshot snapshot;
                try
                {
                    snapshot = ParseSnapshot(text);
                }
                catch (FormatException error)
                {
                    Debug.LogWarning("MoMLocalizerClient: bad message skipped: " + error.Message);
                    continue;
                }
                lock (_lock) { _latest = snapshot; }
            }
        }
        return false;
    }

    // Main thread: apply the newest snapshot, smooth motion, despawn people who left.
    private void Update()
    {
        Snapshot snapshot;
        lock (_lock)
        {
            snapshot = _latest;
            _latest = null;
        }
        float now = Time.time;
        if (snapshot != null)
        {
            LastSeq = snapshot.seq;
            LastCaptureTime = snapshot.t;
            foreach (var person in snapshot.people)
            {
                if (person.confidence < MinConfidence) continue;
                var target = Origin + Scale * new Vector3(person.x, 0f, person.y);
                GameObject go;
                if (!_objects.TryGetValue(person.id, out go) || go == null)
                {
                    go = PersonPrefab != null
                        ? Instantiate(PersonPrefab, target, Quaternion.identity, transform)
                        : CreateDefault(target);
                    go.name = "person " + person.id;
                    _objects[person.id] = go;
                }
                _targets[person.id] = target;
                _lastSeen[person.id] = now;
                var velocity = new Vector3(person.vx, 0f, person.vy);
                if (velocity.sqrMagnitude > 0.01f)
                    go.transform.rotation = Quaternion.LookRotation(velocity.normalized, Vector3.up);
            }
        }

        var gone = new List<int>();
        foreach (var entry in _objects)
        {
            if (entry.Value == null || now - _lastSeen[entry.Key] > DespawnSeconds)
            {
                gone.Add(entry.Key);
                continue;
            }
            var t = entry.Value.transform;
            var target = _targets[entry.Key];
            t.position = Smoothing <= 0f
                ? target
                : Vector3.Lerp(t.position, target, 1f - Mathf.Exp(-Smoothing * Time.deltaTime));
        }
        foreach (var id in gone)
        {
            if (_objects[id] != null) Destroy(_objects[id]);
            _objects.Remove(id);
            _targets.Remove(id);
            _lastSeen.Remove(id);
        }
    }

    private GameObject CreateDefault(Vector3 position)
    {
        // An empty root on the floor point with a 1.7 m capsule standing on it (Unity's capsule is
        // 2 units tall with its pivot in the middle, hence the 0.85 lift and scale).
        var root = new GameObject();
        root.transform.SetParent(transform, false);
        root.transform.position = position;
        var body = GameObject.CreatePrimitive(PrimitiveType.Capsule);
        body.transform.SetParent(root.transform, false);
        body.transform.localPosition = new Vector3(0f, 0.85f, 0f);
        body.transform.localScale = new Vector3(0.5f, 0.85f, 0.5f);
        return root;
    }

    // -- snapshot JSON (schema v1) ----------------------------------------------------------------

    /// <summary>Parse one snapshot message; throws FormatException on malformed JSON.</summary>
    public static Snapshot ParseSnapshot(string text)
    {
        var root = new JsonReader(text).ReadDocument() as Dictionary<string, object>;
        if (root == null) throw new FormatException("a snapshot must be a JSON object");
        var snapshot = new Snapshot
        {
            v = (int)Number(root, "v"),
            seq = (long)Number(root, "seq"),
            t = Number(root, "t"),
        };
        var people = new List<Person>();
        object list;
        if (root.TryGetValue("people", out list) && list is List<object>)
        {
            foreach (var item in (List<object>)list)
            {
                var p = item as Dictionary<string, object>;
                if (p == null) continue;
                var person = new Person
                {
                    id = (int)Number(p, "id"),
                    x = (float)Number(p, "x"),
                    y = (float)Number(p, "y"),
                    vx = (float)Number(p, "vx"),
                    vy = (float)Number(p, "vy"),
                    confidence = (float)Number(p, "confidence"),
                };
                var cameras = new List<int>();
                object cams;
                if (p.TryGetValue("cameras", out cams) && cams is List<object>)
                    foreach (var k in (List<object>)cams)
                        if (k is double) cameras.Add((int)(double)k);
                person.cameras = cameras.ToArray();
                people.Add(person);
            }
        }
        snapshot.people = people.ToArray();
        return snapshot;
    }

    private static double Number(Dictionary<string, object> map, string key)
    {
        object value;
        return map.TryGetValue(key, out value) && value is double ? (double)value : 0.0;
    }

    // A small strict JSON reader: objects -> Dictionary, arrays -> List, numbers -> double.
    private sealed class JsonReader
    {
        private readonly string _s;
        private int _i;

        public JsonReader(string s) { _s = s; }

        public object ReadDocument()
        {
            var value = ReadValue();
            SkipSpace();
            if (_i != _s.Length) throw Error("trailing characters");
            return value;
        }

        private FormatException Error(string what)
        {
            return new FormatException("JSON: " + what + " at " + _i);
        }

        private void SkipSpace()
        {
            while (_i < _s.Length && char.IsWhiteSpace(_s[_i])) _i++;
        }

        private char Peek()
        {
            SkipSpace();
            if (_i >= _s.Length) throw Error("unexpected end");
            return _s[_i];
        }

        private void Expect(char c)
        {
            if (Peek() != c) throw Error("expected '" + c + "'");
            _i++;
        }

        private object ReadValue()
        {
            char c = Peek();
            if (c == '{') return ReadObject();
            if (c == '[') return ReadArray();
            if (c == '"') return ReadString();
            if (Word("true")) return true;
            if (Word("false")) return false;
            if (Word("null")) return null;
            return ReadNumber();
        }

        private bool Word(string word)
        {
            if (string.CompareOrdinal(_s, _i, word, 0, word.Length) != 0) return false;
            _i += word.Length;
            return true;
        }

        private Dictionary<string, object> ReadObject()
        {
            var map = new Dictionary<string, object>();
            Expect('{');
            if (Peek() == '}') { _i++; return map; }
            while (true)
            {
                if (Peek() != '"') throw Error("expected a key");
                var key = ReadString();
                Expect(':');
                map[key] = ReadValue();
                if (Peek() == ',') { _i++; continue; }
                Expect('}');
                return map;
            }
        }

        private List<object> ReadArray()
        {
            var list = new List<object>();
            Expect('[');
            if (Peek() == ']') { _i++; return list; }
            while (true)
            {
                list.Add(ReadValue());
                if (Peek() == ',') { _i++; continue; }
                Expect(']');
                return list;
            }
        }

        private string ReadString()
        {
            Expect('"');
            var sb = new StringBuilder();
            while (true)
            {
                if (_i >= _s.Length) throw Error("unterminated string");
                char c = _s[_i++];
                if (c == '"') return sb.ToString();
                if (c != '\\') { sb.Append(c); continue; }
                if (_i >= _s.Length) throw Error("unterminated escape");
                char e = _s[_i++];
                switch (e)
                {
                    case 'n': sb.Append('\n'); break;
                    case 't': sb.Append('\t'); break;
                    case 'r': sb.Append('\r'); break;
                    case 'b': sb.Append('\b'); break;
                    case 'f': sb.Append('\f'); break;
                    case 'u':
                        if (_i + 4 > _s.Length) throw Error("short \\u escape");
                        sb.Append((char)int.Parse(_s.Substring(_i, 4), NumberStyles.HexNumber, CultureInfo.InvariantCulture));
                        _i += 4;
                        break;
                    default: sb.Append(e); break;  // \" \\ \/
                }
            }
        }

        private double ReadNumber()
        {
            int start = _i;
            while (_i < _s.Length && "+-0123456789.eE".IndexOf(_s[_i]) >= 0) _i++;
            double value;
            if (_i == start || !double.TryParse(_s.Substring(start, _i - start), NumberStyles.Float, CultureInfo.InvariantCulture, out value))
                throw Error("bad value");
            return value;
        }
    }
}
