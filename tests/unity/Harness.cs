// Console harness: runs examples/unity/MoMLocalizerClient.cs the way a Unity scene would (an
// inactive GameObject, fields set as in the inspector, activated, then one Update per frame at
// 50 fps) and reports on stdout, one line each, for tests/e2e/test_unity_client.py:
//
//   LOG|WARN|ERROR <text>     everything the client logged (UnityEngine.Debug)
//   STATE {json}              after each frame that applied a new snapshot: seq, the position of
//                             every person object (Unity x, y, z) and how many exist
//   STATUS {json}             twice a second: connected, attempts, token rejected, last error
//
// Usage: mono Harness.exe URL TOKEN SMOOTHING   (TOKEN "-" for none). Ends on "quit" or EOF.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.Linq;
using System.Text;
using System.Threading;
using UnityEngine;

public static class Harness
{
    private static string F(double v) { return v.ToString("R", CultureInfo.InvariantCulture); }

    private static string Quote(string s)
    {
        return s == null ? "null" : "\"" + s.Replace("\\", "\\\\").Replace("\"", "\\\"") + "\"";
    }

    public static int Main(string[] args)
    {
        var output = new object();
        Debug.Sink = (level, text) => { lock (output) { Console.WriteLine(level + " " + text); Console.Out.Flush(); } };
        var root = new GameObject("momloc");
        root.SetActive(false);
        var client = root.AddComponent<MoMLocalizerClient>();
        client.Url = args[0];
        client.Token = args[1] == "-" ? "" : args[1];
        client.Smoothing = float.Parse(args[2], CultureInfo.InvariantCulture);
        client.MaxBackoffSeconds = 2f;
        root.SetActive(true);

        var quit = new ManualResetEvent(false);
        new Thread(() =>
        {
            string line;
            while ((line = Console.ReadLine()) != null && line.Trim() != "quit") { }
            quit.Set();
        }) { IsBackground = true }.Start();

        long lastSeq = -1;
        int frame = 0;
        const float dt = 0.02f;
        while (!quit.WaitOne(TimeSpan.FromSeconds(dt)))
        {
            StubPlayerLoop.Tick(dt);
            frame++;
            var sb = new StringBuilder();
            if (client.LastSeq != lastSeq)
            {
                lastSeq = client.LastSeq;
                var people = client.People.Where(p => p.Value != null).OrderBy(p => p.Key).Select(p =>
                {
                    var pos = p.Value.transform.position;
                    return "\"" + p.Key + "\":[" + F(pos.x) + "," + F(pos.y) + "," + F(pos.z) + "]";
                });
                int objects = StubPlayerLoop.LiveObjects.Count(go => go.name.StartsWith("person "));
                sb.Append("STATE {\"seq\":" + lastSeq + ",\"t\":" + F(client.LastCaptureTime)
                    + ",\"people\":{" + string.Join(",", people) + "},\"objects\":" + objects + "}\n");
            }
            if (frame % 25 == 0)
            {
                sb.Append("STATUS {\"connected\":" + (client.Connected ? "true" : "false")
                    + ",\"attempts\":" + client.Attempts
                    + ",\"rejected\":" + (client.TokenRejected ? "true" : "false")
                    + ",\"error\":" + Quote(client.LastError) + "}\n");
            }
            if (sb.Length > 0) lock (output) { Console.Write(sb.ToString()); Console.Out.Flush(); }
        }
        root.SetActive(false);
        UnityEngine.Object.Destroy(root);
        return 0;
    }
}
