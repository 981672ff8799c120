// The C# binding through the real library, run by tests/csharp.rs under Mono:
//
//   mcs -out:troupe-tests.exe bindings/csharp/Troupe.cs bindings/csharp/tests/TroupeTests.cs bindings/csharp/tests/Npy.cs
//   LD_LIBRARY_PATH=target/debug mono troupe-tests.exe DEMO_BUNDLE CLIP.npy OUT.f32 TINY_BUNDLE
//
// TINY_BUNDLE: an ARMFlow bundle of other features than the demo's (armflow-tiny-interx); the
// group bundle umf-tiny beside it is loaded too.
//
// Streams CLIP (float32 [T, 22, 3], metres, z up, 120 fps) through the demo model under its
// `mirror` rule, seed 7, one frame per call, and writes the partner's positions to OUT.f32 (raw
// little-endian float32) for the Rust side to compare with its own stream; then checks that
// every misuse is refused with the right exception and leaves the session as it was. Prints one
// line per check and "ALL PASSED" at the end; exits non-zero on the first failure.
using System;
using System.Collections.Generic;
using System.IO;
using System.Text;
using Troupe;

internal static class TroupeTests
{
    private static int checks;

    private static void Check(bool ok, string what)
    {
        if (!ok) throw new Exception("FAILED: " + what);
        checks++;
        Console.WriteLine("ok: " + what);
    }

    private static T Throws<T>(Action action, string what) where T : Exception
    {
        try
        {
            action();
        }
        catch (T e)
        {
            Check(true, what + " -> " + e.GetType().Name + " (" + e.Message + ")");
            return e;
        }
        catch (Exception e)
        {
            throw new Exception("FAILED: " + what + ": expected " + typeof(T).Name + ", got " + e.GetType().Name + ": " + e.Message);
        }
        throw new Exception("FAILED: " + what + ": expected " + typeof(T).Name + ", nothing was thrown");
    }

    private static int Main(string[] args)
    {
        if (args.Length != 4)
        {
            Console.Error.WriteLine("usage: troupe-tests.exe DEMO_BUNDLE CLIP.npy OUT.f32 TINY_BUNDLE");
            return 2;
        }
        try
        {
            Run(args[0], args[1], args[2], args[3]);
            Console.WriteLine("ALL PASSED (" + checks + " checks)");
            return 0;
        }
        catch (Exception e)
        {
            Console.WriteLine(e.Message);
            Console.WriteLine(e.StackTrace);
            return 1;
        }
    }

    private static void Run(string demoBundle, string clipPath, string outPath, string tinyBundle)
    {
        Check(Model.AbiVersion == 1, "the library speaks ABI 1");
        string assembly = typeof(Model).Assembly.GetName().Version.ToString(3);
        Check(Model.Version == assembly, "library " + Model.Version + ", binding " + assembly);

        int[] shape;
        float[] clip = Npy.Read(clipPath, out shape);
        Check(shape.Length == 3 && shape[1] == 22 && shape[2] == 3, "the clip is [T, 22, 3]");
        int frames = shape[0];
        const int Pose = 22 * 3;

        var format = new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f };
        var partner = new List<float>();
        using (var model = Model.Load(demoBundle))
        {
            Check(string.Join(",", model.ConditionLabels) == "mirror,follow,keep-away", "the demo model's rules");
            Check(model.FrameDim == 262 && model.Fps == 30 && model.FramesPerToken == 4, "the demo model's sizes");
            using (var session = model.CreateSession(new SessionOptions { Seed = 7 }))
            {
                session.SetCondition("mirror");
                session.SetJointsFormat(format);
                var frame = new float[Pose];
                var poses = new float[4 * Pose];
                for (int t = 0; t < frames; t++)
                {
                    Array.Copy(clip, t * Pose, frame, 0, Pose);
                    int ready = session.JointsReadyAfter(1);
                    int n = session.StepJoints(frame, 1, poses);
                    if (n != ready) throw new Exception("FAILED: frame " + t + ": " + n + " poses, " + ready + " announced");
                    for (int i = 0; i < n * Pose; i++) partner.Add(poses[i]);
                }
                Check(partner.Count > 0 && partner.Count % Pose == 0, "streamed " + frames + " frames, " + partner.Count / Pose + " partner poses back");
            }
        }
        using (var w = new BinaryWriter(File.Create(outPath)))
            foreach (float v in partner) w.Write(v);

        Misuse(demoBundle, tinyBundle, clip);
        Rigs(demoBundle, clipPath, clip, format);
        LibraryChecks(demoBundle);
        ModelAndSessionChecks(demoBundle, tinyBundle, clip);
        MotionChecks(demoBundle);
        FamilyChecks(demoBundle, clip);
    }

    /// <summary>Rotations for a Humanoid, takes from BVH and FBX files, rigs, retargeting and the
    /// rig writers, each read back; misuse refused.</summary>
    private static void Rigs(string demoBundle, string clipPath, float[] clip, JointsFormat format)
    {
        const int Pose = 22 * 3;
        using (var model = Model.Load(demoBundle))
        using (var session = model.CreateSession(new SessionOptions { Seed = 7 }))
        {
            session.SetJointsFormat(format);
            var frame = new float[Pose];
            var positions = new float[8 * Pose];
            var rotations = new float[8 * 22 * 4];
            int got = 0;
            for (int t = 0; t < 120 && got == 0; t++)
            {
                Array.Copy(clip, t * Pose, frame, 0, Pose);
                got = session.StepJoints(frame, 1, positions, rotations);
            }
            Check(got > 0, "poses with rotations");
            double norm = 0;
            for (int k = 0; k < 4; k++) norm += rotations[k] * rotations[k];
            Check(Math.Abs(norm - 1.0) < 1e-4, "a unit rotation per joint");
        }

        string data = Path.GetFullPath(Path.Combine(Path.GetDirectoryName(clipPath), ".."));
        string fbx = Path.Combine(data, "blender_mixamo.fbx");
        Take take = Take.Read(fbx);
        Check(take.Frames == 4 && take.Positions.Length == 4 * Pose && take.Format.Units == Units.Metres, "Blender's FBX as a take");
        Check(take.Mapping[0] == "mixamorig:Hips" && take.Inferred.Length == 0, "its mapping: " + take.Mapping[0]);
        Throws<IoException>(() => Take.Read("/nonexistent.fbx"), "a take that does not exist");
        Throws<ArgumentNullException>(() => Take.Read(null), "a null take path");

        using (Rig rig = Rig.FromFile(fbx))
        {
            Check(rig.JointCount == 22 && rig.JointName(0) == "mixamorig:Hips" && rig.JointName(22) == null, "the FBX rig");
            using (var retargeter = new Retargeter(rig, format))
            {
                var rot = new float[rig.JointCount * 4];
                var root = new float[3];
                int moving = retargeter.Push(clip, rot, root);
                Check(moving == 0 && !float.IsNaN(root[1]), "a frame retargeted onto it");
                Check(retargeter.Mapping()[0] == 0, "the pelvis drives the hips");
                Throws<ArgumentException>(() => retargeter.Push(clip, new float[3], root), "too few rotations");
                retargeter.Reset();
            }
            string dir = Path.Combine(Path.GetTempPath(), "troupe-cs-rig-" + Guid.NewGuid().ToString("N"));
            Directory.CreateDirectory(dir);
            try
            {
                string outFbx = Path.Combine(dir, "partner.fbx"), outBvh = Path.Combine(dir, "partner.bvh"), glb = Path.Combine(dir, "scene.glb");
                rig.WriteFbx(outFbx, clip, 60, format);
                rig.WriteBvh(outBvh, clip, 60, format);
                rig.WriteGltf(glb, new[] { "actor" }, clip, 60, format);
                Check(Take.Read(outFbx).Frames == 60 && Take.Read(outBvh).Frames == 60, "FBX and BVH on the rig read back");
                using (Rig fromGlb = Rig.FromGltf(glb)) Check(fromGlb.JointCount == 22, "the glTF's skin as a rig");
                using (Rig again = Rig.FromFile(outFbx)) Check(again.JointName(0) == "mixamorig:Hips", "the FBX written, as a rig");
                Throws<InvalidArgumentException>(() => rig.WriteFbx(outFbx, clip, 60, format, (Units)9), "units 9");
                Throws<ArgumentException>(() => rig.WriteFbx(outFbx, clip, 0, format), "no frames");
                Throws<InvalidArgumentException>(() => Rig.FromGltf(glb, 3), "a skin the file lacks");
            }
            finally
            {
                Directory.Delete(dir, true);
            }
        }
        Throws<InvalidArgumentException>(() => Rig.FromJson("{ not json"), "a rig document that is not JSON");
        Settings(demoBundle, clip, format);
        Generators(demoBundle);
    }

    /// <summary>Whole-clip generation: ARFlow's reaction and ARMFlow's official clip loop,
    /// seeded (the same seed, the same frames), finite, and refused by other families.</summary>
    private static void Generators(string demoBundle)
    {
        string bundles = Path.GetDirectoryName(Path.GetFullPath(demoBundle));
        using (var arflow = Model.Load(Path.Combine(bundles, "arflow-tiny")))
        using (var armflow = Model.Load(Path.Combine(bundles, "armflow-tiny-interhuman")))
        {
            const int Frames = 8;
            var actor = new float[Frames * arflow.FrameDim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Sin(0.01 * i);
            var opt = new ArflowOptions { Seed = 5, Steps = 2, Guidance = 0f };
            float[] a = arflow.ArflowGenerate(actor, Frames, opt), b = arflow.ArflowGenerate(actor, Frames, opt);
            Check(a.Length == Frames * arflow.FrameDim && AllFinite(a) && SameValues(a, b), "an ARFlow reaction, seeded");
            Throws<UnsupportedException>(() => armflow.ArflowGenerate(new float[Frames * armflow.FrameDim], Frames), "ARFlow on ARMFlow");
            Throws<ArgumentException>(() => arflow.ArflowGenerate(actor, Frames + 1), "too few actor frames");
            Throws<InvalidArgumentException>(() => arflow.ArflowGenerate(actor, Frames, new ArflowOptions { Steps = 0 }), "zero steps");

            Check(armflow.ClipFrames > 0, "ARMFlow's clip length");
            var clipActor = new float[armflow.ClipFrames * armflow.FrameDim];
            for (int i = 0; i < clipActor.Length; i++) clipActor[i] = (float)Math.Cos(0.01 * i);
            var copt = new ClipOptions { Seed = 9, Steps = 1 };
            float[] c1 = armflow.ArmflowClip(clipActor, armflow.ClipFrames, null, copt);
            float[] c2 = armflow.ArmflowClip(clipActor, armflow.ClipFrames, null, copt);
            Check(c1.Length == armflow.ClipFrames * armflow.FrameDim && AllFinite(c1) && SameValues(c1, c2), "an ARMFlow clip, seeded");
            Throws<UnsupportedException>(() => arflow.ArmflowClip(actor, 1), "a clip on ARFlow");
        }
    }

    private static string Bundle(string demoBundle, string name)
    {
        return Path.Combine(Path.GetDirectoryName(Path.GetFullPath(demoBundle)), name);
    }

    private static float MaxDiff(float[] a, float[] b, int n)
    {
        float worst = 0f;
        for (int i = 0; i < n; i++) worst = Math.Max(worst, Math.Abs(a[i] - b[i]));
        return worst;
    }

    /// <summary>Limits, the call budget, the progress and log callbacks, struct mirrors and the
    /// library's error message as the exceptions carry it.</summary>
    private static void LibraryChecks(string demoBundle)
    {
        Library.CheckStructSizes();
        Check(true, "every struct mirror has the library's size");
        Limits limits = Library.Limits;
        Check(limits.MaxSteps == 10000 && limits.MaxComputeThreads == 1024 && limits.MaxPeople >= 256,
            "limits: " + limits.MaxSteps + " steps, " + limits.MaxComputeThreads + " compute threads, " + limits.MaxPeople + " people");
        int compute = Model.ComputeThreads;
        Throws<InvalidArgumentException>(() => Model.ComputeThreads = (int)limits.MaxComputeThreads + 1, "compute threads past the limit");
        Check(Model.ComputeThreads == compute, "the refused setting left the threads as they were");

        // The call budget: ARFlow's work is its sampler steps.
        using (var arflow = Model.Load(Bundle(demoBundle, "arflow-tiny")))
        {
            var actor = new float[8 * arflow.FrameDim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Sin(0.01 * i);
            var opt = new ArflowOptions { Seed = 5, Steps = 2, Guidance = 0f };
            Library.SetCallBudget(1, 0);
            try
            {
                Throws<InvalidArgumentException>(() => arflow.ArflowGenerate(actor, 8, opt), "2 steps over a budget of 1");
                Throws<InvalidArgumentException>(() => Library.SetCallBudget(0, -1), "a negative time budget");
                Throws<InvalidArgumentException>(() => Library.SetCallBudget(0, double.NaN), "a NaN time budget");
                Throws<InvalidArgumentException>(() => arflow.ArflowGenerate(actor, 8, opt), "the refused budgets kept the one set");
                Check(arflow.ArflowGenerate(actor, 8, new ArflowOptions { Steps = 1, Guidance = 0f }).Length == 8 * 262, "1 step within it");
            }
            finally
            {
                Library.SetCallBudget(0, 0);
            }
            Check(arflow.ArflowGenerate(actor, 8, opt).Length == 8 * 262, "no budget: 2 steps run");
        }

        // Progress: a load cancelled at its first report, one counted, one whose callback throws.
        Library.SetProgressCallback((done, total) => false);
        try
        {
            Throws<CancelledException>(() => Model.Load(demoBundle), "a load its progress callback cancels");
            long reports = 0;
            bool ordered = true;
            ulong last = 0, lastTotal = 0;
            Library.SetProgressCallback((done, total) =>
            {
                reports++;
                ordered &= done <= total && done >= last;
                last = done;
                lastTotal = total;
                return true;
            });
            using (var m = Model.Load(demoBundle)) Check(m.FrameDim == 262, "a load reporting its progress");
            Check(reports >= 3 && ordered && last == lastTotal, reports + " progress reports, in order, ending at " + last + " of " + lastTotal);
            Library.SetProgressCallback((done, total) => { throw new InvalidOperationException("callback failed"); });
            try
            {
                Model.Load(demoBundle).Dispose();
                throw new Exception("FAILED: a throwing progress callback did not cancel the load");
            }
            catch (CancelledException e)
            {
                Check(e.InnerException is InvalidOperationException && e.InnerException.Message == "callback failed",
                    "a progress callback that throws cancels the call, its exception inside (" + e.Message + ")");
            }
            Library.SetProgressCallback(null);
            long before = reports;
            using (var m = Model.Load(demoBundle)) Check(m.FrameDim == 262 && reports == before, "no callback: nothing reported");
        }
        finally
        {
            Library.SetProgressCallback(null);
        }

        // The log: a load's records reach the callback at debug level, none once it is removed.
        long records = 0, badLevels = 0;
        Library.SetLogCallback((level, target, message) =>
        {
            System.Threading.Interlocked.Increment(ref records);
            if (level < LogLevel.Error || level > LogLevel.Debug || message.Length == 0) System.Threading.Interlocked.Increment(ref badLevels);
        }, LogLevel.Debug);
        try
        {
            Model.Load(demoBundle).Dispose();
            long seen = System.Threading.Interlocked.Read(ref records);
            Check(seen > 0 && badLevels == 0, seen + " log records of a load, each with a level and a message");
            Throws<InvalidArgumentException>(() => Library.SetLogCallback((l, t, m) => { }, (LogLevel)9), "log level 9");
            Model.Load(demoBundle).Dispose();
            Check(System.Threading.Interlocked.Read(ref records) > seen, "the refused level kept the callback that was set");
            Library.SetLogCallback((l, t, m) => { throw new InvalidOperationException("log failed"); }, LogLevel.Debug);
            Model.Load(demoBundle).Dispose();
            Check(true, "a log callback that throws does not reach native code");
            Library.SetLogCallback(null);
            long after = System.Threading.Interlocked.Read(ref records);
            Model.Load(demoBundle).Dispose();
            Check(System.Threading.Interlocked.Read(ref records) == after, "no callback: no records");
        }
        finally
        {
            Library.SetLogCallback(null);
        }
    }

    /// <summary>Model queries, prompts and text features, capabilities, queued noise, ARMFlow's
    /// own session options, ARFlow stream settings, crowds.</summary>
    private static void ModelAndSessionChecks(string demoBundle, string tinyBundle, float[] clip)
    {
        using (var demo = Model.Load(demoBundle))
        using (var int8 = Model.Load(Bundle(demoBundle, "armflow-demo-int8")))
        using (var umf = Model.Load(Bundle(demoBundle, "umf-tiny")))
        {
            Check(demo.ReducedPrecision.Count == 0, "a float32 bundle has no reduced-precision graphs");
            var graphs = new List<string>();
            foreach (var g in int8.ReducedPrecision) graphs.Add(g.Key + "=" + g.Value);
            Check(string.Join(",", graphs) == "context_layers=int8,velocity=int8", "the int8 bundle's graphs: " + string.Join(",", graphs));
            using (var s = demo.CreateSession())
            {
                bool bounded = true;
                for (int k = 1; k <= 12; k++) bounded &= s.OutputFrames(k) <= demo.MaxOutputFrames(k);
                Check(bounded && demo.MaxOutputFrames(4) >= 4 && umf.MaxOutputFrames(4) == 0, "MaxOutputFrames bounds every step");
                Throws<ArgumentOutOfRangeException>(() => demo.MaxOutputFrames(-1), "negative frames");
                SessionCapabilities caps = s.Capabilities;
                Check((caps & SessionCapabilities.Condition) != 0 && (caps & SessionCapabilities.QueuedNormals) != 0
                    && (caps & SessionCapabilities.Prompt) == 0, "the demo stream's capabilities: " + caps);
                Throws<InvalidArgumentException>(() => s.JointsPlacement(), "a placement before any joint frame");
                s.SetJointsFormat(new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f });
                s.StepJoints(clip, 8, new float[8 * 66]);
                Placement p = s.JointsPlacement();
                double norm = p.HeadingW * p.HeadingW + p.HeadingX * p.HeadingX + p.HeadingY * p.HeadingY + p.HeadingZ * p.HeadingZ;
                Check(Math.Abs(norm - 1) < 1e-9 && Math.Abs(p.HeadingX) < 1e-12 && Math.Abs(p.HeadingZ) < 1e-12 && !double.IsNaN(p.Floor),
                    "the joint stream's placement: floor " + p.Floor + ", a turn about +Y");
            }

            // Prompts and CLIP features.
            Check(umf.TakesPrompts && umf.ConditionDim > 0, "the UMF bundle takes prompts");
            float[] p1 = umf.EncodePrompt("two people shake hands"), p2 = umf.EncodePrompt("two people shake hands");
            float[] p3 = umf.EncodePrompt("two people fight");
            Check(p1.Length == umf.ConditionDim && AllFinite(p1) && SameValues(p1, p2) && !SameValues(p1, p3), "a prompt's condition, the same twice");
            Throws<InvalidArgumentException>(() => demo.EncodePrompt("hello"), "a prompt to a bundle without text");
            Throws<ArgumentNullException>(() => umf.EncodePrompt(null), "a null prompt");
            int width = umf.TextTokenDim;
            var tokens = new float[4 * width];
            for (int i = 0; i < tokens.Length; i++) tokens[i] = 0.01f * (i % 17);
            float[] t1 = umf.EncodeText(tokens, 4, 3), t2 = umf.EncodeText(tokens, 4, 2);
            Check(width > 0 && t1.Length == umf.ConditionDim && AllFinite(t1) && !SameValues(t1, t2), "CLIP features to a condition (" + width + " wide)");
            Throws<InvalidArgumentException>(() => umf.EncodeText(tokens, 4, 4), "an end-of-text index past the tokens");
            Throws<ArgumentException>(() => umf.EncodeText(tokens, 5, 0), "more tokens than the array holds");
            Check(demo.TextTokenDim == 0, "the demo bundle has no text branch");

            // ARMFlow's own session options.
            using (var mean = demo.Armflow.CreateSession(new SessionOptions { Seed = 4 }, new ArmflowSessionOptions { ActorLatent = ActorLatent.Mean }))
            using (var sample = demo.Armflow.CreateSession(new SessionOptions { Seed = 4 }, new ArmflowSessionOptions { ActorLatent = ActorLatent.Sample }))
            using (var guided = demo.Armflow.CreateSession(null, new ArmflowSessionOptions { CfgScale = 2f }))
            {
                var fmt = new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f };
                mean.SetJointsFormat(fmt);
                sample.SetJointsFormat(fmt);
                var a = new float[40 * 66];
                var b = new float[40 * 66];
                int na = mean.StepJoints(clip, 160, a), nb = sample.StepJoints(clip, 160, b);
                Check(na == nb && na > 0 && !SameValues(a, b), "the posterior mean and sample streams differ (" + na + " poses)");
                Check((guided.Capabilities & SessionCapabilities.CfgScale) != 0, "a guided ARMFlow stream takes a CFG scale");
                Throws<UnsupportedException>(() => guided.SetPrompt("wave"), "a prompt to it");
            }
            Throws<InvalidArgumentException>(() => demo.Armflow.CreateSession(null, new ArmflowSessionOptions { CfgScale = float.NaN }), "a NaN CFG scale");
            Throws<UnsupportedException>(() => umf.Armflow.CreateSession(), "an ARMFlow stream of a UMF model");
            Check(demo.Armflow.ClipTokens == 0, "the demo model has no official clip");
        }

        // Queued normals and queued token noise replay the same draws; misuse leaves the stream.
        using (var tiny = Model.Load(tinyBundle))
        using (var a = tiny.CreateSession(new SessionOptions { Seed = 1 }))
        using (var b = tiny.CreateSession(new SessionOptions { Seed = 1 }))
        using (var c = tiny.CreateSession(new SessionOptions { Seed = 1 }))
        {
            int dim = tiny.FrameDim, latent = tiny.LatentDim;
            var actor = new float[32 * dim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Sin(0.01 * i);
            var normals = new float[2 * latent];
            for (int i = 0; i < normals.Length; i++) normals[i] = (float)Math.Sin(0.7 * i + 0.3);
            var actorNoise = new float[latent];
            var reactorNoise = new float[latent];
            Array.Copy(normals, 0, actorNoise, 0, latent);
            Array.Copy(normals, latent, reactorNoise, 0, latent);
            Throws<InvalidArgumentException>(() => a.QueueNormals(new float[latent + 1]), "normals that are not whole tokens");
            var nan = (float[])normals.Clone();
            nan[3] = float.NaN;
            Throws<InvalidArgumentException>(() => a.QueueNormals(nan), "a NaN normal");
            Throws<ArgumentException>(() => b.Armflow.QueueNoise(actorNoise, new float[latent + 1]), "token noise of two lengths");
            Throws<ShapeMismatchException>(() => b.Armflow.QueueNoise(new float[latent + 1], new float[latent + 1]), "token noise of the wrong length");
            a.QueueNormals(normals);
            b.Armflow.QueueNoise(actorNoise, reactorNoise);
            var oa = new float[32 * dim];
            var ob = new float[32 * dim];
            var oc = new float[32 * dim];
            int na = a.Step(actor, 32, oa), nb = b.Step(actor, 32, ob), nc = c.Step(actor, 32, oc);
            Check(na == nb && na == nc && na > 0 && SameValues(oa, ob), "queued normals and queued token noise give the same stream");
            Check(!SameValues(oa, oc), "and it is not the seeded one");
            Throws<UnsupportedException>(() => { using (var umf = Model.Load(Bundle(demoBundle, "umf-tiny"))) umf.CreateSession(); }, "no stream of UMF");
        }

        // A crowd in one call equals each session stepped alone.
        using (var tiny = Model.Load(tinyBundle))
        using (var other = Model.Load(tinyBundle))
        using (var alone = tiny.CreateSession(new SessionOptions { Seed = 2 }))
        using (var c1 = tiny.CreateSession(new SessionOptions { Seed = 2 }))
        using (var c2 = tiny.CreateSession(new SessionOptions { Seed = 2 }))
        using (var foreign = other.CreateSession(new SessionOptions { Seed = 2 }))
        {
            int dim = tiny.FrameDim;
            var actor = new float[32 * dim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Cos(0.013 * i);
            var expected = new float[32 * dim];
            int m = alone.Step(actor, 32, expected);
            var chunk = new float[4 * dim];
            var o1 = new float[8 * dim];
            var o2 = new float[8 * dim];
            var crowd1 = new List<float>();
            var crowd2 = new List<float>();
            Throws<InvalidArgumentException>(() => Sessions.Step(new[] { c1, c1 }, new[] { chunk, chunk }, new[] { 4, 4 }, new[] { o1, o2 }), "a session listed twice");
            Throws<InvalidArgumentException>(() => Sessions.Step(new[] { c1, foreign }, new[] { chunk, chunk }, new[] { 4, 4 }, new[] { o1, o2 }), "sessions of two models");
            Throws<ArgumentException>(() => Sessions.Step(new[] { c1, c2 }, new[] { chunk }, new[] { 4, 4 }, new[] { o1, o2 }), "arrays of different lengths");
            Throws<ArgumentException>(() => Sessions.Step(new[] { c1, c2 }, new[] { chunk, chunk }, new[] { 5, 4 }, new[] { o1, o2 }), "more frames than an array holds");
            for (int t = 0; t < 32; t += 4)
            {
                Array.Copy(actor, t * dim, chunk, 0, 4 * dim);
                int[] written = Sessions.Step(new[] { c1, c2 }, new[] { chunk, chunk }, new[] { 4, 4 }, new[] { o1, o2 });
                for (int i = 0; i < written[0] * dim; i++) crowd1.Add(o1[i]);
                for (int i = 0; i < written[1] * dim; i++) crowd2.Add(o2[i]);
            }
            float[] f1 = crowd1.ToArray(), f2 = crowd2.ToArray();
            Check(f1.Length == m * dim && f2.Length == m * dim && MaxDiff(f1, expected, f1.Length) <= 1e-5f && MaxDiff(f2, expected, f2.Length) <= 1e-5f,
                "a crowd of 2 stepped together equals a session alone (" + m + " frames; the refused calls changed nothing)");
            int[] none = Sessions.Step(new Session[0], new float[0][], new int[0], new float[0][]);
            Check(none.Length == 0, "an empty crowd");
        }
    }

    /// <summary>The skeleton, positions to features and back, the joint stream, metrics, SMPL-X
    /// posing, and the BVH, JSON, viewer and glTF writers, each read back.</summary>
    private static void MotionChecks(string demoBundle)
    {
        Check(Motion.JointCount == 22 && Motion.JointName(0) == "pelvis" && Motion.JointName(22) == null && Motion.JointName(-1) == null,
            "the t2m-22 joints");
        int[] parents = Motion.Parents;
        float[] offsets = Motion.RestOffsets;
        Check(parents.Length == 22 && parents[0] == -1 && parents[4] == 1 && offsets.Length == 66, "the skeleton's parents and offsets");
        // The neutral body walking along z, 40 frames, metres, y up, 30 fps.
        const int Frames = 40;
        var rest = new float[66];
        for (int j = 0; j < 22; j++)
            for (int d = 0; d < 3; d++)
                rest[j * 3 + d] = offsets[j * 3 + d] + (parents[j] >= 0 ? rest[parents[j] * 3 + d] : 0f);
        var walk = new float[Frames * 66];
        for (int t = 0; t < Frames; t++)
            for (int k = 0; k < 66; k++) walk[t * 66 + k] = rest[k] + (k % 3 == 2 ? 0.02f * t : 0f);
        var fmt = new JointsFormat { Units = Units.Metres, Up = UpAxis.Y, Handedness = Handedness.Right, Fps = 30f };

        using (var model = Model.Load(demoBundle))
        {
            Check(Motion.EncodedFrames(model, fmt, Frames) == Frames - 1, "40 frames encode to 39");
            Placement placement;
            float[] features = Motion.Encode(model, fmt, walk, Frames, out placement);
            Check(features.Length == (Frames - 1) * 262 && AllFinite(features), "the walk as features");
            Poses back = Motion.Decode(model, fmt, placement, features, Frames - 1);
            Check(back.Frames == Frames - 1 && MaxDiff(back.Positions, walk, back.Positions.Length) < 1e-5f, "decoded back to the walk's positions");
            Check(back.Rotations.Length == 39 * 88 && back.Rotations6d.Length == 39 * 132 && back.Contacts.Length == 39 * 4 && AllFinite(back.Rotations),
                "with rotations, 6-D rotations and contacts");
            Placement again;
            float[] same = Motion.Encode(model, fmt, walk, Frames, out again, placement);
            Check(same.Length == features.Length && MaxDiff(same, features, same.Length) < 1e-5f && again.Floor == placement.Floor,
                "encoded again in the placement it gave");
            var nan = (float[])walk.Clone();
            nan[5] = float.NaN;
            Throws<InvalidArgumentException>(() => Motion.Encode(model, fmt, nan, Frames, out again), "a NaN position");
            Throws<ArgumentException>(() => Motion.Encode(model, fmt, walk, Frames + 1, out again), "more frames than the array holds");
            Throws<ArgumentException>(() => Motion.Decode(model, fmt, placement, features, Frames), "more feature frames than the array holds");
            var bad = placement;
            bad.HeadingW = 0;
            Throws<InvalidArgumentException>(() => Motion.Decode(model, fmt, bad, features, Frames - 1), "a placement whose turn is not a unit quaternion");

            // The same walk a frame at a time: the stream's frames are Encode's, a frame late.
            using (var stream = new MotionStream(model, fmt))
            {
                Check(MotionStream.LatencyFrames == 1 && stream.MaxFrames == 1, "a stream's latency and most frames per push");
                Throws<InvalidArgumentException>(() => stream.Placement(), "a stream's placement before its first frame");
                var frame = new float[66];
                var outFrame = new float[262];
                var streamed = new List<float>();
                for (int t = 0; t < Frames; t++)
                {
                    Array.Copy(walk, t * 66, frame, 0, 66);
                    if (t == 10)
                    {
                        var bent = (float[])frame.Clone();
                        bent[7] = float.PositiveInfinity;
                        Throws<InvalidArgumentException>(() => stream.Push(bent, outFrame), "an infinite position pushed");
                        Throws<BufferTooSmallException>(() => stream.Push(frame, new float[0]), "no room for the feature frame");
                        Throws<ArgumentException>(() => stream.Push(new float[65], outFrame), "a frame of 65 floats");
                    }
                    int n = stream.Push(frame, outFrame);
                    if (t == 0) Check(n == 0, "the first frame completes no feature frame");
                    for (int i = 0; i < n * 262; i++) streamed.Add(outFrame[i]);
                }
                float[] s = streamed.ToArray();
                Check(s.Length == features.Length && MaxDiff(s, features, s.Length) < 1e-4f, "the stream's features are Encode's (refused pushes changed nothing)");
                Check(Math.Abs(stream.Placement().Floor - placement.Floor) < 1e-6, "the stream's placement is Encode's");
                var moved = placement;
                moved.OriginX += 1.0;
                stream.Reset(moved);
                Check(Math.Abs(stream.Placement().OriginX - moved.OriginX) < 1e-12, "a reset to a given placement");
                Throws<InvalidArgumentException>(() => stream.Reset(bad), "a reset to a bad placement");
                Check(Math.Abs(stream.Placement().OriginX - moved.OriginX) < 1e-12, "which leaves the placement as it was");
                stream.Reset();
                Throws<InvalidArgumentException>(() => stream.Placement(), "a reset forgets the placement");
                stream.Dispose();
                stream.Dispose();
                Throws<ObjectDisposedException>(() => stream.Push(frame, outFrame), "a push on a disposed stream");
            }
        }

        // Two people: the walk and itself 5 cm aside intersect in every frame; 5 m aside, never.
        var aside = (float[])walk.Clone();
        var far = (float[])walk.Clone();
        for (int i = 0; i < aside.Length; i += 3) { aside[i] += 0.05f; far[i] += 5f; }
        PenetrationMetrics close = Motion.Penetration(walk, aside, Frames), apart = Motion.Penetration(walk, far, Frames);
        Check(close.FramesIntersecting == Frames && close.Frequency == 1.0 && close.MaxDepth > 0 && close.DepthSum >= close.MaxDepth,
            "5 cm aside: every frame intersects, " + close.MaxDepth + " m deep at most");
        Check(apart.FramesIntersecting == 0 && apart.Frequency == 0 && apart.MaxDepth == 0, "5 m aside: none does");
        var nanWalk = (float[])walk.Clone();
        nanWalk[0] = float.NaN;
        Throws<InvalidArgumentException>(() => Motion.Penetration(nanWalk, aside, Frames), "a NaN position in the metrics");
        Throws<ArgumentNullException>(() => Motion.Penetration(walk, null, Frames), "a null second person");

        // MAGNet's SMPL-X frames posed on the skeleton.
        int[] shape;
        float[] pair = Npy.Read(Path.Combine(Bundle(demoBundle, "magnet-tiny"), "golden", "frames.npy"), out shape);
        var first = new float[4 * 145];
        for (int t = 0; t < 4; t++) Array.Copy(pair, t * 2 * 145, first, t * 145, 145);
        float[] posed = Motion.Smplx145Positions(first, 4);
        Check(posed.Length == 4 * 66 && AllFinite(posed) && posed[3 * 15 + 1] > posed[1], "SMPL-X frames posed: the head above the pelvis");
        first[20] = float.NaN;
        Throws<InvalidArgumentException>(() => Motion.Smplx145Positions(first, 4), "a NaN SMPL-X value");
        Throws<ArgumentException>(() => Motion.Smplx145Positions(first, 5), "more SMPL-X frames than the array holds");

        // Files: BVH, JSON, the viewer, glTF of people of two lengths, a clip retargeted.
        string dir = Path.Combine(Path.GetTempPath(), "troupe-cs-motion-" + Guid.NewGuid().ToString("N"));
        Directory.CreateDirectory(dir);
        try
        {
            string bvh = Path.Combine(dir, "walk.bvh"), json = Path.Combine(dir, "walk.json"), html = Path.Combine(dir, "walk.html");
            Motion.WriteBvh(bvh, new[] { "actor" }, walk, Frames, fmt);
            Take take = Take.Read(bvh);
            Check(take.Frames == Frames && take.Mapping[0] == "pelvis" && take.Mapping[21] == "right_wrist" && take.Format.Units == Units.Centimetres,
                "the BVH written reads back");
            Check(Math.Abs(take.Positions[3 * 15 + 1] / 100f - walk[3 * 15 + 1]) < 1e-4f, "with the walk's head height");
            string two = Path.Combine(dir, "two.bvh");
            var pairWalk = new float[2 * Frames * 66];
            Array.Copy(walk, pairWalk, walk.Length);
            Array.Copy(far, 0, pairWalk, walk.Length, far.Length);
            Motion.WriteBvh(two, new string[] { null, "partner" }, pairWalk, Frames, fmt, Units.Metres, false);
            Check(File.ReadAllText(two).Contains("partner") && File.ReadAllText(two).Contains("person1"), "two people, one named by default");
            Throws<InvalidArgumentException>(() => Motion.WriteBvh(Path.Combine(dir, "bad.bvh"), new[] { "a b" }, walk, Frames, fmt), "a name with a space");
            Check(!File.Exists(Path.Combine(dir, "bad.bvh")), "nothing left of the refused file");
            Throws<ArgumentException>(() => Motion.WriteBvh(bvh, new[] { "a", "b" }, walk, Frames, fmt), "two people in one person's array");

            Motion.WriteJson(json, new[] { "actor" }, walk, Frames, fmt);
            string doc = File.ReadAllText(json);
            Check(doc.Contains("\"actor\"") && doc.Contains("pelvis"), "the JSON document names the person and the joints");
            string badJson = Path.Combine(dir, "bad.json");
            Throws<InvalidArgumentException>(() => Motion.WriteJson(badJson, new[] { "actor" }, nanWalk, Frames, fmt), "JSON of a NaN position");
            Check(!File.Exists(badJson), "nothing left of it");

            Motion.WriteViewer(html, null, new[] { "actor" }, walk, Frames, fmt, "a walk from C#");
            string page = File.ReadAllText(html);
            Check(page.Contains("a walk from C#") && page.Contains("actor"), "the HTML player, titled");
            Throws<ArgumentNullException>(() => Motion.WriteViewer(null, null, new[] { "actor" }, walk, Frames, fmt), "a viewer with no path");
            var nine = new float[9 * Frames * 66];
            Throws<InvalidArgumentException>(() => Motion.WriteViewer(html, null, new string[9], nine, Frames, fmt), "nine people in the viewer");

            using (Rig rig = Rig.FromFile(bvh))
            {
                RigClip rc = rig.RetargetClip(walk, Frames, fmt);
                bool unit = true;
                for (int q = 0; q < rc.Rotations.Length; q += 4)
                {
                    double n2 = rc.Rotations[q] * rc.Rotations[q] + rc.Rotations[q + 1] * rc.Rotations[q + 1]
                        + rc.Rotations[q + 2] * rc.Rotations[q + 2] + rc.Rotations[q + 3] * rc.Rotations[q + 3];
                    unit &= Math.Abs(n2 - 1) < 1e-4;
                }
                Check(rc.Frames == Frames && rc.Joints == 22 && rc.Rotations.Length == Frames * 88 && rc.RootJoint == 0 && unit,
                    "the walk retargeted as a clip: unit rotations, the root moving");
                Check(Math.Abs(rc.RootTranslations[3 * 39 + 2] - rc.RootTranslations[2] - 0.78f * 100f) < 1.0f,
                    "the root walked 78 cm along z (" + (rc.RootTranslations[3 * 39 + 2] - rc.RootTranslations[2]) + " cm)");
                nanWalk[0] = float.NaN;
                Throws<InvalidArgumentException>(() => rig.RetargetClip(nanWalk, Frames, fmt), "a NaN position retargeted");
                Throws<ArgumentException>(() => rig.RetargetClip(walk, 0, fmt), "a clip of no frames");

                string glb = Path.Combine(dir, "people.glb");
                var half = new float[(Frames / 2) * 66];
                Array.Copy(far, half, half.Length);
                Motion.WriteGltf(glb, new[] { new PersonClip { Name = "actor", Positions = walk, Frames = Frames },
                                              new PersonClip { Name = "late", Positions = half, Frames = Frames / 2 } }, fmt, rig);
                using (Rig fromGlb = Rig.FromGltf(glb)) Check(fromGlb.JointCount == 22, "glTF people of two lengths on the rig");
                string own = Path.Combine(dir, "own.glb");
                Motion.WriteGltf(own, new[] { new PersonClip { Positions = walk, Frames = Frames } }, fmt, null, RetargetFlags.NoBodies);
                Check(new FileInfo(own).Length > 0 && new FileInfo(own).Length < new FileInfo(glb).Length, "glTF on troupe's own body, no bodies");
                Throws<InvalidArgumentException>(() => Motion.WriteGltf(own, new[] { new PersonClip { Positions = walk, Frames = 0 } }, fmt),
                    "a person of no frames");
                Throws<ArgumentException>(() => Motion.WriteGltf(own, new[] { new PersonClip { Positions = half, Frames = Frames } }, fmt),
                    "a person with fewer positions than frames");
            }
        }
        finally
        {
            Directory.Delete(dir, true);
        }
    }

    /// <summary>Whole generation per family: UMF groups (seeded, given noise), MAGNet tasks
    /// (seeded, given draws), ARFlow with given draws and stream settings, ARMFlow's clip.</summary>
    private static void FamilyChecks(string demoBundle, float[] clip)
    {
        using (var umf = Model.Load(Bundle(demoBundle, "umf-tiny")))
        using (var demo = Model.Load(demoBundle))
        {
            Check(umf.Umf.Stages == 2 && umf.Umf.Tokens == 16 && umf.ClipFrames == 40, "the UMF bundle's stages, tokens, clip");
            Check(demo.Umf.Stages == 0 && demo.Umf.Tokens == 0, "the demo model is no UMF model");
            int size = 2 * umf.ClipFrames * umf.FrameDim;
            float[] g1 = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 3 }), g2 = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 3 });
            float[] g3 = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 4 });
            Check(g1.Length == size && AllFinite(g1) && SameValues(g1, g2) && !SameValues(g1, g3), "a group of 2, seeded");
            float[] text = umf.EncodePrompt("two people shake hands");
            Check(!SameValues(umf.Umf.GenerateGroup(text, 2, new UmfOptions { Seed = 3 }), g1), "a prompt changes the group");
            float[] coarse = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 3, StageSteps = new uint[] { 1, 1 }, StageSolvers = new[] { Solver.Euler, Solver.Euler } });
            Check(coarse.Length == size && !SameValues(coarse, g1), "other solvers and steps per stage change it");
            int prior, jumps, reactions;
            umf.Umf.NoiseLengths(2, out prior, out jumps, out reactions);
            Check(prior > 0 && jumps > 0 && reactions > 0, "noise lengths " + prior + ", " + jumps + ", " + reactions);
            var noise = new UmfNoise { Prior = new float[prior], Jumps = new float[jumps], Reactions = new float[reactions] };
            for (int i = 0; i < prior; i++) noise.Prior[i] = (float)Math.Sin(0.1 * i);
            for (int i = 0; i < jumps; i++) noise.Jumps[i] = (float)Math.Cos(0.1 * i);
            for (int i = 0; i < reactions; i++) noise.Reactions[i] = (float)Math.Sin(0.3 * i + 1);
            float[] n1 = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 3 }, noise), n2 = umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 99 }, noise);
            Check(SameValues(n1, n2) && !SameValues(n1, g1), "given noise: the seed no longer matters");
            var shortNoise = new UmfNoise { Prior = new float[prior - 1], Jumps = noise.Jumps, Reactions = noise.Reactions };
            Throws<ShapeMismatchException>(() => umf.Umf.GenerateGroup(null, 2, null, shortNoise), "noise of the wrong length");
            Throws<ShapeMismatchException>(() => umf.Umf.GenerateGroup(new float[umf.ConditionDim + 1], 2), "a condition of the wrong length");
            Throws<ArgumentOutOfRangeException>(() => umf.Umf.GenerateGroup(null, 0), "a group of no one");
            Throws<InvalidArgumentException>(() => umf.Umf.GenerateGroup(null, 257), "a group of 257");
            Throws<InvalidArgumentException>(() => umf.Umf.GenerateGroup(null, 2, new UmfOptions { StageSteps = new uint[] { 0, 0 } }), "zero steps per stage");
            Throws<ArgumentException>(() => umf.Umf.GenerateGroup(null, 2, new UmfOptions { StageSteps = new uint[] { 1 } }), "steps for one stage of two");
            Throws<UnsupportedException>(() => demo.Umf.GenerateGroup(null, 1), "a group of the demo model");
            Check(SameValues(umf.Umf.GenerateGroup(null, 2, new UmfOptions { Seed = 3 }), g1), "the refused calls changed nothing");
            Throws<UnsupportedException>(() => { int a, b, c; demo.Umf.NoiseLengths(2, out a, out b, out c); }, "noise lengths of the demo model");
        }

        using (var magnet = Model.Load(Bundle(demoBundle, "magnet-tiny")))
        using (var umf = Model.Load(Bundle(demoBundle, "umf-tiny")))
        {
            IList<string> configs = magnet.Magnet.Configs;
            Check(magnet.Magnet.People == 2 && configs.Count == 8 && configs.Contains("dd100"), "MAGNet's people and configurations: " + string.Join(",", configs));
            Check(umf.Magnet.People == 0 && umf.Magnet.Configs.Count == 0, "a UMF model has none");
            int[] shape;
            float[] frames = Npy.Read(Path.Combine(Bundle(demoBundle, "magnet-tiny"), "golden", "frames.npy"), out shape);
            Check(shape.Length == 3 && shape[0] == 128 && shape[1] == 2 && shape[2] == 145, "128 frames of 2 people");
            var opt = new MagnetOptions { Samples = 1, Steps = 2, SeqLen = 64, NoX0Guidance = true };
            MagnetShape s = magnet.Magnet.OutputShape("dd100", 128, opt);
            Check(s.Samples == 1 && s.Frames == 64 && s.People == 2, "the output's shape");
            float[] m1 = magnet.Magnet.Generate("dd100", frames, 128, opt), m2 = magnet.Magnet.Generate("dd100", frames, 128, opt);
            Check(m1.Length == 64 * 2 * 145 && AllFinite(m1) && SameValues(m1, m2), "a MAGNet task, the same twice");
            var seeded = new MagnetOptions { Samples = 1, Steps = 2, SeqLen = 64, NoX0Guidance = true, Seed = 12345 };
            Check(!SameValues(magnet.Magnet.Generate("dd100", frames, 128, seeded), m1), "another seed, another run");
            var draws = new float[1 << 20];
            for (int i = 0; i < draws.Length; i++) draws[i] = (float)Math.Sin(0.37 * i);
            int used, used2;
            float[] d1 = magnet.Magnet.GenerateWithDraws("dd100", frames, 128, draws, out used, opt);
            float[] d2 = magnet.Magnet.GenerateWithDraws("dd100", frames, 128, draws, out used2, seeded);
            Check(used > 0 && used < draws.Length && used2 == used && d1.Length == m1.Length && SameValues(d1, d2) && !SameValues(d1, m1),
                "given draws (" + used + " taken): the seed no longer matters");
            var few = new float[used - 1];
            Throws<InvalidArgumentException>(() => magnet.Magnet.GenerateWithDraws("dd100", frames, 128, few, out used2, opt), "one draw too few");
            Throws<InvalidArgumentException>(() => magnet.Magnet.Generate("nope", frames, 128, opt), "an unknown configuration");
            Throws<InvalidArgumentException>(() => magnet.Magnet.OutputShape("nope", 128, opt), "its shape");
            Throws<ArgumentException>(() => magnet.Magnet.Generate("dd100", frames, 129, opt), "more frames than the array holds");
            Throws<ArgumentException>(() => magnet.Magnet.Generate("dd100", frames, 128, opt, new byte[10]), "too few presence bytes");
            Throws<ArgumentException>(() => magnet.Magnet.Generate("dd100", frames, 128, new MagnetOptions { Keyframes = new uint[9] }), "nine key frames");
            var present = new byte[128 * 2];
            for (int i = 0; i < present.Length; i++) present[i] = 1;
            Check(SameValues(magnet.Magnet.Generate("dd100", frames, 128, opt, present), m1), "everyone present is the default");
            Throws<UnsupportedException>(() => umf.Magnet.Generate("dd100", new float[0], 0), "a MAGNet task of a UMF model");
        }

        using (var arflow = Model.Load(Bundle(demoBundle, "arflow-tiny")))
        using (var online = Model.Load(Bundle(demoBundle, "arflow-tiny-online")))
        using (var demo = Model.Load(demoBundle))
        {
            const int Frames = 8;
            var actor = new float[Frames * 262];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Sin(0.01 * i);
            var draws = new float[4 * Frames * 262];
            for (int i = 0; i < draws.Length; i++) draws[i] = (float)Math.Cos(0.29 * i);
            var opt = new ArflowOptions { Seed = 1, Steps = 2, Guidance = 0f, Eta = 0.5f };
            int used, used2;
            float[] a = arflow.Arflow.GenerateWithDraws(actor, Frames, draws, out used, opt);
            float[] b = arflow.Arflow.GenerateWithDraws(actor, Frames, draws, out used2, new ArflowOptions { Seed = 2, Steps = 2, Guidance = 0f, Eta = 0.5f });
            Check(used == 2 * Frames * 262 && used2 == used && SameValues(a, b) && AllFinite(a), "ARFlow with given draws: one ε per step, the seed unused");
            Check(!SameValues(a, arflow.Arflow.Generate(actor, Frames, opt)), "and not the seeded run");
            arflow.Arflow.GenerateWithDraws(actor, Frames, draws, out used, new ArflowOptions { Steps = 2, Guidance = 0f });
            Check(used == 0, "a deterministic run takes no draws");
            Throws<InvalidArgumentException>(() => arflow.Arflow.GenerateWithDraws(actor, Frames, new float[used2 - 1], out used, opt), "one draw too few");
            Throws<InvalidArgumentException>(() => arflow.ArflowGenerate(actor, Frames, new ArflowOptions { Weight = 2f }), "a weight of 2");
            Throws<UnsupportedException>(() => demo.Arflow.GenerateWithDraws(new float[262], 1, draws, out used), "ARFlow draws on ARMFlow");
            float[] hinge = arflow.ArflowGenerate(actor, Frames, new ArflowOptions { Seed = 1, Steps = 2, Flags = ArflowFlags.SquaredHinge, Sigma = 0.5f });
            Check(hinge.Length == Frames * 262 && AllFinite(hinge), "flags and start noise taken");

            // The online stream's settings: fewer steps, another stream; misuse refused.
            var fmt = new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f };
            using (var one = online.CreateSession())
            using (var five = online.CreateSession())
            {
                one.Arflow.SetOptions(new ArflowOptions { Steps = 1 });
                Throws<InvalidArgumentException>(() => one.Arflow.SetOptions(new ArflowOptions { Weight = 2f }), "a stream weight of 2");
                one.SetJointsFormat(fmt);
                five.SetJointsFormat(fmt);
                var p1 = new float[40 * 66];
                var p5 = new float[40 * 66];
                int n1 = one.StepJoints(clip, 160, p1), n5 = five.StepJoints(clip, 160, p5);
                Check(n1 == n5 && n1 > 0 && AllFinite(p1) && !SameValues(p1, p5), "a 1-step ARFlow stream differs from the default (" + n1 + " poses)");
                Throws<InvalidArgumentException>(() => one.Arflow.SetOptions(new ArflowOptions { Steps = 3 }), "new steps once the stream started");
                one.Arflow.SetOptions(new ArflowOptions { Steps = 1, Seed = 8 });
                Check(true, "the same steps and a new seed are taken mid-stream");
            }
            using (var reactor = demo.CreateSession())
                Throws<UnsupportedException>(() => reactor.Arflow.SetOptions(new ArflowOptions()), "ARFlow settings on an ARMFlow stream");
        }

        using (var armflow = Model.Load(Bundle(demoBundle, "armflow-tiny-interhuman")))
        {
            int tokens = armflow.Armflow.ClipTokens;
            Check(tokens > 0 && tokens * armflow.FramesPerToken >= armflow.ClipFrames, "an official clip of " + tokens + " tokens, " + armflow.ClipFrames + " frames");
            var actor = new float[armflow.ClipFrames * armflow.FrameDim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Cos(0.01 * i);
            var copt = new ClipOptions { Seed = 9, Steps = 1 };
            Check(SameValues(armflow.Armflow.GenerateClip(actor, armflow.ClipFrames, null, copt), armflow.ArmflowClip(actor, armflow.ClipFrames, null, copt)),
                "Model.Armflow.Clip is Model.ArmflowClip");
        }
    }

    private static bool AllFinite(float[] v)
    {
        foreach (float x in v) if (float.IsNaN(x) || float.IsInfinity(x)) return false;
        return true;
    }

    private static bool SameValues(float[] a, float[] b)
    {
        if (a.Length != b.Length) return false;
        for (int i = 0; i < a.Length; i++) if (a[i] != b[i]) return false;
        return true;
    }

    /// <summary>Process-wide settings, model sizes, per-session settings, sealed snapshots.</summary>
    private static void Settings(string demoBundle, float[] clip, JointsFormat format)
    {
        Check(Model.VersionNumber == 0x200, "version number " + Model.VersionNumber);
        int compute = Model.ComputeThreads, load = Model.LoadThreads;
        Model.ComputeThreads = 1;
        Model.LoadThreads = 1;
        Check(Model.ComputeThreads == 1 && Model.LoadThreads == 1, "threads set");
        Model.ComputeThreads = compute;
        Model.LoadThreads = load;
        Throws<ArgumentOutOfRangeException>(() => Model.ComputeThreads = -1, "negative threads");
        using (var model = Model.Load(demoBundle))
        {
            Check(model.JointsLatencyFrames > model.LatencyFrames && model.LatentDim > 0, "latencies and latent width");
            Check(!model.TakesPrompts, "the demo model takes no prompts (" + model.TakesPrompts + ", clip " + model.ClipFrames + ")");
            using (var session = model.CreateSession(new SessionOptions { Seed = 3 }))
            {
                session.SetSteps(2);
                session.SetCfgScale(1.5f);
                Throws<InvalidArgumentException>(() => session.SetSteps(0), "zero steps");
                Throws<InvalidArgumentException>(() => session.SetCfgScale(float.NaN), "a NaN guidance scale");
                Throws<UnsupportedException>(() => session.SetPrompt("two people dance"), "a prompt to a model without text");
                Check(session.OutputFrames(4) >= 0, "output frames");
                session.SetJointsFormat(format);
                var poses = new float[8 * 66];
                var frame = new float[66];
                for (int t = 0; t < 40; t++)
                {
                    Array.Copy(clip, t * 66, frame, 0, 66);
                    session.StepJoints(frame, 1, poses);
                }
                byte[] key = new byte[32], other = new byte[32];
                for (int i = 0; i < 32; i++) { key[i] = (byte)i; other[i] = (byte)(i + 1); }
                byte[] sealedBytes = Model.Seal(session.Snapshot(), key);
                using (var resumed = model.RestoreSealed(sealedBytes, key)) Check(resumed != null, "a sealed snapshot restored");
                Throws<InvalidArgumentException>(() => model.RestoreSealed(sealedBytes, other), "a sealed snapshot under another key");
            }
        }
    }

    private static void Misuse(string demoBundle, string tinyBundle, float[] clip)
    {
        Throws<ArgumentNullException>(() => Model.Load(null), "a null path");
        Throws<IoException>(() => Model.Load("/nonexistent/bundle"), "a path that does not exist");
        string corrupt = Path.Combine(Path.GetTempPath(), "troupe-cs-corrupt-" + Guid.NewGuid().ToString("N"));
        Directory.CreateDirectory(corrupt);
        File.WriteAllText(Path.Combine(corrupt, "troupe.json"), "{ not json");
        try
        {
            Throws<ModelException>(() => Model.Load(corrupt), "a corrupt manifest");
        }
        finally
        {
            Directory.Delete(corrupt, true);
        }
        Throws<IoException>(() => Model.LoadMemory(new byte[] { 1, 2, 3 }), "three bytes as an archive (not a readable tar)");
        Throws<ArgumentException>(() => Model.Load("bad\0path"), "a path with a NUL");

        using (var model = Model.Load(demoBundle))
        {
            Throws<InvalidArgumentException>(() => model.CreateSession(new SessionOptions { Steps = 0 }), "zero steps");
            Throws<InvalidArgumentException>(() => model.CreateSession(new SessionOptions { CfgScale = float.NaN }), "a NaN guidance scale");
            var a = model.CreateSession(new SessionOptions { Seed = 3 });
            var b = model.CreateSession(new SessionOptions { Seed = 3 });
            var format = new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f };
            a.SetJointsFormat(format);
            b.SetJointsFormat(format);
            Throws<InvalidArgumentException>(() => a.SetCondition("dance"), "an unknown rule");
            Throws<InvalidArgumentException>(() => a.SetJointsFormat(new JointsFormat { Units = Units.Metres, Up = UpAxis.Y, Fps = -1f }), "a negative frame rate");
            var frames = new float[40 * 66];
            Array.Copy(clip, frames, frames.Length);
            var poses = new float[16 * 66];
            Throws<ArgumentNullException>(() => a.StepJoints(null, 1, poses), "null positions");
            Throws<ArgumentException>(() => a.StepJoints(frames, 41, poses), "more frames than the array holds");
            var nan = (float[])frames.Clone();
            nan[100] = float.NaN;
            Throws<InvalidArgumentException>(() => a.StepJoints(nan, 40, poses), "a NaN coordinate");
            Throws<BufferTooSmallException>(() => a.StepJoints(frames, 40, new float[66]), "an output array too small");
            a.SetFootLock(true);
            b.SetFootLock(true);
            a.SetRootSmoothing(true);
            b.SetRootSmoothing(true);
            a.Armflow.SetRecentring(true);
            b.Armflow.SetRecentring(true);
            Throws<InvalidArgumentException>(() => a.Armflow.SetRecentring(true, 0f), "a zero recentring distance");
            Throws<InvalidArgumentException>(() => a.SetRootSmoothing(true, 0f), "a zero smoothing time constant");
            Throws<InvalidArgumentException>(() => a.SetFootLock(true, 0.5f, 0), "a foot lock releasing over zero frames");
            Throws<InvalidArgumentException>(() => a.SetFootLock(true, float.NaN), "a NaN contact threshold");
            Throws<InvalidArgumentException>(() => a.SetPenetrationGuard(true, -1f), "a negative guard margin");
            // The refused calls left `a` as it was: it streams exactly as `b`, which saw none of them.
            var pa = new float[16 * 66];
            var pb = new float[16 * 66];
            int na = a.StepJoints(frames, 40, pa), nb = b.StepJoints(frames, 40, pb);
            bool same = na == nb && na > 0;
            for (int i = 0; i < na * 66 && same; i++) same = pa[i] == pb[i];
            Check(same, "after every refused call the session streams as one that saw none (" + na + " poses)");
            model.Dispose();
            // Sessions keep the model alive: they work after the Model is disposed.
            a.SetCondition("follow");
            Check(a.StepJoints(frames, 4, pa) >= 0, "a session outlives its disposed Model");
            Throws<ObjectDisposedException>(() => model.CreateSession(), "a session from a disposed Model");
            a.Dispose();
            a.Dispose();
            Throws<ObjectDisposedException>(() => a.StepJoints(frames, 1, pa), "a step on a disposed Session");
            b.Dispose();
        }

        using (var tiny = Model.Load(tinyBundle))
        using (var s = tiny.CreateSession())
        {
            Throws<UnsupportedException>(() => s.SetJointsFormat(JointsFormat.Default), "joint positions on a bundle of other features");
            int dim = tiny.FrameDim;
            var actor = new float[32 * dim];
            for (int i = 0; i < actor.Length; i++) actor[i] = (float)Math.Sin(0.01 * i);
            var output = new float[32 * dim];
            Throws<ArgumentException>(() => s.Step(new float[dim - 1], 1, output), "a frame shorter than FrameDim");
            int n = s.Step(actor, 32, output);
            Check(n > 0 && n <= 32, "features in, " + n + " reactor frames out");
            s.Reset();
            Check(s.Step(actor, 32, output) == n, "after Reset the stream starts again");

            // A snapshot after 28 frames, restored: the rest of the stream is the same, bit for bit.
            s.Reset();
            var head = new float[32 * dim];
            int h = s.Step(actor, 28, head);
            byte[] snapshot = s.Snapshot();
            Check(snapshot.Length > 64 && tiny.Identity.Length == 32, "a " + snapshot.Length + "-byte snapshot");
            var rest = new float[36 * dim];
            var tail = new float[4 * dim];
            Array.Copy(actor, 28 * dim, tail, 0, tail.Length);
            int r;
            using (var restored = tiny.Restore(snapshot))
                r = restored.Step(tail, 4, rest);
            bool equal = h + r == n;
            for (int i = 0; equal && i < n * dim; i++)
                equal = (i < h * dim ? head[i] : rest[i - h * dim]) == output[i];
            Check(equal, "the restored stream continues bit for bit (" + h + " + " + r + " frames)");
            snapshot[snapshot.Length / 2] ^= 1;
            var altered = Throws<InvalidArgumentException>(() => tiny.Restore(snapshot), "an altered snapshot");
            Check(altered.Message.Contains("checksum") && altered.StatusName == "TROUPE_ERR_INVALID_ARG",
                "the exception carries the library's message (troupe_last_error_copy)");
        }

        // A group model (UMF) streams nothing: its family does not offer sessions.
        using (var group = Model.Load(Path.Combine(Path.GetDirectoryName(Path.GetFullPath(tinyBundle)), "umf-tiny")))
            Throws<UnsupportedException>(() => group.CreateSession(), "a session of a group model");

        // Every streaming family takes joint positions: ARFlow's online stream, guarded. 400 frames
        // at 120 fps are 100 at 30, less the one frame features wait for.
        using (var online = Model.Load(Path.Combine(Path.GetDirectoryName(Path.GetFullPath(tinyBundle)), "arflow-tiny-online")))
        using (var s = online.CreateSession())
        {
            s.SetJointsFormat(new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f });
            s.SetPenetrationGuard(true);
            var poses = new float[100 * 66];
            int n = s.StepJoints(clip, 400, poses);
            Check(n == 99, "an ARFlow stream returns 99 poses for 400 joint frames (got " + n + ")");
            bool finite = true;
            for (int i = 0; i < n * 66; i++)
                finite &= !float.IsNaN(poses[i]) && !float.IsInfinity(poses[i]);
            Check(finite, "its poses are finite");
            Throws<UnsupportedException>(() => s.Armflow.SetRecentring(true), "ARMFlow's recentring on an ARFlow stream");
            Throws<UnsupportedException>(() => s.Magnet.SetEarlyEmission(true), "a MAGNet setting on an ARFlow stream");
        }

        // ... and a MAGNet live partner (its SMPL-X frames by inverse kinematics), after its opening:
        // the second person of the bundle's golden pair. Its latency is a window of frames.
        string bundles = Path.GetDirectoryName(Path.GetFullPath(tinyBundle));
        using (var magnet = Model.Load(Path.Combine(bundles, "magnet-tiny")))
        using (var s = magnet.CreateSession())
        {
            Check(magnet.Family == "magnet", "the model names its family (" + magnet.Family + ")");
            int[] shape;
            float[] pair = Npy.Read(Path.Combine(bundles, "magnet-tiny", "golden", "frames.npy"), out shape);
            var opening = new float[32 * 145];
            for (int t = 0; t < 32; t++) Array.Copy(pair, (t * 2 + 1) * 145, opening, t * 145, 145);
            Throws<ArgumentException>(() => s.Magnet.SetPartnerOpening(opening, 33), "more opening frames than the array holds");
            s.Magnet.SetPartnerOpening(opening, 32);
            s.SetJointsFormat(new JointsFormat { Units = Units.Metres, Up = UpAxis.Z, Handedness = Handedness.Right, Fps = 120f });
            s.SetPenetrationGuard(true);
            var poses = new float[Math.Max(1, s.JointsReadyAfter(400)) * 66];
            int n = s.StepJoints(clip, 400, poses);
            Check(n > 0 && n <= 100, "a MAGNet partner returns poses for 400 joint frames at 120 fps (got " + n + ")");
            bool finite = true;
            for (int i = 0; i < n * 66; i++)
                finite &= !float.IsNaN(poses[i]) && !float.IsInfinity(poses[i]);
            Check(finite, "its poses are finite");
            Throws<UnsupportedException>(() => s.SetFootLock(true), "the foot lock on frames without contact labels");
            Throws<UnsupportedException>(() => s.Armflow.SetRecentring(true), "ARMFlow's recentring on a MAGNet partner");
        }
    }
}
