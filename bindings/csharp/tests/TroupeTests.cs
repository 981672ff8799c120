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

    private static void Throws<T>(Action action, string what) where T : Exception
    {
        try
        {
            action();
        }
        catch (T e)
        {
            Check(true, what + " -> " + e.GetType().Name + " (" + e.Message + ")");
            return;
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
            Throws<InvalidArgumentException>(() => tiny.Restore(snapshot), "an altered snapshot");
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
