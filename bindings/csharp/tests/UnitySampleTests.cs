// The Unity sample (unity/Samples~/AnimatorPartner/TroupePartner.cs) on the engine's clock,
// without the editor: compiled with the binding and UnityStub.cs, it runs the demo model at 20,
// 60 and 144 engine frames a second (each frame's length jittered by up to a quarter), 60 s each,
// with an actor Animator playing the CMU clip. The model comes from a StreamingAssets folder at
// 20 fps (the partner shown as spheres), from a TextAsset at 60 fps and through UnityWebRequest
// from an Android APK's StreamingAssets at 144 fps (both driving a Humanoid partner character).
// Checked: the poses held stay bounded, the playhead keeps pace with the actor (it ends within
// one token of where it was behind once the first poses arrived), the partner moves, and the
// partner character's bones, posed by the rotations the sample applies, point where the
// partner's joints are.
//
//   LD_LIBRARY_PATH=target/debug mono unity-sample-tests.exe BUNDLES_DIR CLIP.npy APK_DIR
//   (APK_DIR/assets/armflow-demo.tar: the demo bundle, scripts/bundle-tar.sh)
using System;
using System.Collections.Generic;
using System.IO;
using System.Reflection;
using System.Text;
using Troupe;
using Troupe.Samples;
using UnityEngine;

static class UnitySampleTests
{
    private const int Token = 4;

    // t2m-22's joint index for each Humanoid bone the sample asks for.
    private static readonly Dictionary<HumanBodyBones, int> Joint = new Dictionary<HumanBodyBones, int>
    {
        { HumanBodyBones.Hips, 0 }, { HumanBodyBones.LeftUpperLeg, 1 }, { HumanBodyBones.RightUpperLeg, 2 },
        { HumanBodyBones.Spine, 3 }, { HumanBodyBones.LeftLowerLeg, 4 }, { HumanBodyBones.RightLowerLeg, 5 },
        { HumanBodyBones.Chest, 6 }, { HumanBodyBones.LeftFoot, 7 }, { HumanBodyBones.RightFoot, 8 },
        { HumanBodyBones.UpperChest, 9 }, { HumanBodyBones.LeftToes, 10 }, { HumanBodyBones.RightToes, 11 },
        { HumanBodyBones.Neck, 12 }, { HumanBodyBones.LeftShoulder, 13 }, { HumanBodyBones.RightShoulder, 14 },
        { HumanBodyBones.Head, 15 }, { HumanBodyBones.LeftUpperArm, 16 }, { HumanBodyBones.RightUpperArm, 17 },
        { HumanBodyBones.LeftLowerArm, 18 }, { HumanBodyBones.RightLowerArm, 19 }, { HumanBodyBones.LeftHand, 20 },
        { HumanBodyBones.RightHand, 21 },
    };

    private static void Expect<T>(Action action) where T : Exception
    {
        try { action(); }
        catch (T) { return; }
        throw new Exception("FAILED: expected " + typeof(T).Name);
    }

    // Calls a MonoBehaviour message; a coroutine (Start) runs to its end, as the engine would.
    private static void Call(object target, string method)
    {
        object result = target.GetType().GetMethod(method, BindingFlags.Instance | BindingFlags.NonPublic).Invoke(target, null);
        var routine = result as System.Collections.IEnumerator;
        while (routine != null && routine.MoveNext()) { }
    }

    // A Humanoid partner character in a T-pose (in its armature's axes: Y up, facing +Z, its left
    // at -X), under an armature placed 2 m aside and turned a quarter about Y, with a finger the
    // joint map does not name; no UpperChest, as many rigs have none.
    private static Dictionary<HumanBodyBones, Transform> Character()
    {
        var b = new Dictionary<HumanBodyBones, Transform>();
        var armature = new Transform("Armature", null, new UnityEngine.Vector3(2f, 0f, 1f));
        armature.localRotation = new Quaternion(0f, (float)Math.Sqrt(0.5), 0f, (float)Math.Sqrt(0.5));
        Func<HumanBodyBones, Transform, float, float, float, Transform> add = (bone, parent, x, y, z) =>
            b[bone] = new Transform("mixamorig:" + bone, parent, new UnityEngine.Vector3(x, y, z));
        add(HumanBodyBones.Hips, armature, 0f, 0.95f, 0f);
        add(HumanBodyBones.Spine, b[HumanBodyBones.Hips], 0f, 0.1f, 0f);
        add(HumanBodyBones.Chest, b[HumanBodyBones.Spine], 0f, 0.15f, 0f);
        add(HumanBodyBones.Neck, b[HumanBodyBones.Chest], 0f, 0.25f, 0f);
        add(HumanBodyBones.Head, b[HumanBodyBones.Neck], 0f, 0.1f, 0.02f);
        foreach (int side in new[] { -1, 1 })
        {
            bool left = side < 0;
            var upperLeg = add(left ? HumanBodyBones.LeftUpperLeg : HumanBodyBones.RightUpperLeg, b[HumanBodyBones.Hips], side * 0.09f, -0.06f, 0f);
            var lowerLeg = add(left ? HumanBodyBones.LeftLowerLeg : HumanBodyBones.RightLowerLeg, upperLeg, 0f, -0.4f, 0f);
            var foot = add(left ? HumanBodyBones.LeftFoot : HumanBodyBones.RightFoot, lowerLeg, 0f, -0.42f, 0f);
            add(left ? HumanBodyBones.LeftToes : HumanBodyBones.RightToes, foot, 0f, -0.05f, 0.13f);
            var shoulder = add(left ? HumanBodyBones.LeftShoulder : HumanBodyBones.RightShoulder, b[HumanBodyBones.Chest], side * 0.05f, 0.2f, 0f);
            var upperArm = add(left ? HumanBodyBones.LeftUpperArm : HumanBodyBones.RightUpperArm, shoulder, side * 0.12f, 0f, 0f);
            var lowerArm = add(left ? HumanBodyBones.LeftLowerArm : HumanBodyBones.RightLowerArm, upperArm, side * 0.27f, 0f, 0f);
            var hand = add(left ? HumanBodyBones.LeftHand : HumanBodyBones.RightHand, lowerArm, side * 0.25f, 0f, 0f);
            new Transform(left ? "LeftIndex" : "RightIndex", hand, new UnityEngine.Vector3(side * 0.08f, 0f, 0f));
        }
        return b;
    }

    private static UnityEngine.Vector3 At(float[] shown, int joint)
    {
        return new UnityEngine.Vector3(shown[3 * joint], shown[3 * joint + 1], shown[3 * joint + 2]);
    }

    // With limb IK, the character's wrists go where the partner's are, the partner scaled by the
    // ratio of leg lengths about the hip centre: the largest miss, in metres.
    private static double WristError(Dictionary<HumanBodyBones, Transform> character, float[] shown)
    {
        Func<int, int, float> span = (a, b) => (At(shown, a) - At(shown, b)).magnitude;
        double sourceLegs = span(1, 4) + span(4, 7) + span(2, 5) + span(5, 8);
        Func<HumanBodyBones, HumanBodyBones, float> bone = (a, b) => (character[a].position - character[b].position).magnitude;
        double rigLegs = bone(HumanBodyBones.LeftUpperLeg, HumanBodyBones.LeftLowerLeg) + bone(HumanBodyBones.LeftLowerLeg, HumanBodyBones.LeftFoot)
            + bone(HumanBodyBones.RightUpperLeg, HumanBodyBones.RightLowerLeg) + bone(HumanBodyBones.RightLowerLeg, HumanBodyBones.RightFoot);
        float scale = (float)(rigLegs / sourceLegs);
        UnityEngine.Vector3 sourceHips = (At(shown, 1) + At(shown, 2)) * 0.5f;
        UnityEngine.Vector3 rigHips = (character[HumanBodyBones.LeftUpperLeg].position + character[HumanBodyBones.RightUpperLeg].position) * 0.5f;
        double worst = 0;
        foreach (var wrist in new[] { HumanBodyBones.LeftHand, HumanBodyBones.RightHand })
        {
            UnityEngine.Vector3 want = (At(shown, Joint[wrist]) - sourceHips) * scale;
            worst = Math.Max(worst, ((character[wrist].position - rigHips) - want).magnitude);
        }
        return worst;
    }

    // How far, across the floor, the character's hip centre is from the partner's: the hips'
    // position the sample applies moves the character with the partner.
    private static double HipMiss(Dictionary<HumanBodyBones, Transform> character, float[] shown)
    {
        UnityEngine.Vector3 source = (At(shown, 1) + At(shown, 2)) * 0.5f;
        UnityEngine.Vector3 rig = (character[HumanBodyBones.LeftUpperLeg].position + character[HumanBodyBones.RightUpperLeg].position) * 0.5f;
        return Math.Sqrt((rig.x - source.x) * (rig.x - source.x) + (rig.z - source.z) * (rig.z - source.z));
    }

    // Bones whose direction the partner's joints give: (bone, its child) as t2m-22 joints.
    private static readonly HumanBodyBones[][] Limbs =
    {
        new[] { HumanBodyBones.LeftUpperLeg, HumanBodyBones.LeftLowerLeg }, new[] { HumanBodyBones.LeftLowerLeg, HumanBodyBones.LeftFoot },
        new[] { HumanBodyBones.RightUpperLeg, HumanBodyBones.RightLowerLeg }, new[] { HumanBodyBones.RightLowerLeg, HumanBodyBones.RightFoot },
        new[] { HumanBodyBones.LeftUpperArm, HumanBodyBones.LeftLowerArm }, new[] { HumanBodyBones.LeftLowerArm, HumanBodyBones.LeftHand },
        new[] { HumanBodyBones.RightUpperArm, HumanBodyBones.RightLowerArm }, new[] { HumanBodyBones.RightLowerArm, HumanBodyBones.RightHand },
    };

    // The largest angle, in degrees, between a limb of the posed character and the same limb of
    // the partner's joints.
    private static double LimbError(Dictionary<HumanBodyBones, Transform> character, float[] shown)
    {
        double worst = 0;
        foreach (var limb in Limbs)
        {
            UnityEngine.Vector3 bone = character[limb[1]].position - character[limb[0]].position;
            int a = Joint[limb[0]] * 3, c = Joint[limb[1]] * 3;
            var joint = new UnityEngine.Vector3(shown[c] - shown[a], shown[c + 1] - shown[a + 1], shown[c + 2] - shown[a + 2]);
            double cos = UnityEngine.Vector3.Dot(bone, joint) / (bone.magnitude * joint.magnitude);
            worst = Math.Max(worst, Math.Acos(Math.Max(-1.0, Math.Min(1.0, cos))) * 180.0 / Math.PI);
        }
        return worst;
    }

    private static int Main(string[] args)
    {
        if (args.Length != 3)
        {
            Console.Error.WriteLine("usage: unity-sample-tests.exe BUNDLES_DIR CLIP.npy APK_DIR");
            return 2;
        }
        // PosePlayback's own contract: misuse refused, interpolation between two poses.
        var play = new PosePlayback(2, 30f);
        var two = new float[2];
        Expect<ArgumentNullException>(() => play.Push(null, 1));
        Expect<ArgumentException>(() => play.Push(new float[3], 2));
        Expect<ArgumentOutOfRangeException>(() => play.Sample(-1f, two));
        Expect<ArgumentOutOfRangeException>(() => play.Sample(float.NaN, two));
        Expect<ArgumentOutOfRangeException>(() => new PosePlayback(66, 0f));
        if (play.Sample(0.1f, two)) throw new Exception("FAILED: a pose before any was pushed");
        play.Push(new[] { 0f, 0f, 10f, 20f }, 2);
        play.Sample(0.5f / 30f, two);
        if (Math.Abs(two[0] - 5f) > 1e-4 || Math.Abs(two[1] - 10f) > 1e-4)
            throw new Exception("FAILED: half way between two poses gave " + two[0] + ", " + two[1]);
        play.Sample(1f, two);
        if (two[0] != 10f || play.Queued != 1) throw new Exception("FAILED: the last pose is held");

        byte[] archive = File.ReadAllBytes(Path.Combine(args[2], "assets", "armflow-demo.tar"));
        UnityEngine.Networking.UnityWebRequest.apkRoot = args[2];
        int[] shape;
        float[] clip = Npy.Read(args[1], out shape); // [T, 22, 3], metres, Z up, 120 fps
        int clipFrames = shape[0];
        bool failed = false;
        foreach (int fps in new[] { 20, 60, 144 })
        {
            var rng = new Random(fps);
            double now = 0;
            var bones = new Transform[22];
            for (int j = 0; j < 22; j++) bones[j] = new Transform();
            var animator = new Animator { bones = b => bones[Joint[b]] };
            var partner = new TroupePartner { actor = animator };
            Dictionary<HumanBodyBones, Transform> character = null;
            int requestsBefore = UnityEngine.Networking.UnityWebRequest.requests;
            Application.streamingAssetsPath = args[0];
            if (fps != 20)
            {
                character = Character();
                var characterBones = character;
                partner.partnerCharacter = new Animator
                {
                    bones = b => { Transform t; return characterBones.TryGetValue(b, out t) ? t : null; },
                };
            }
            if (fps == 60) partner.bundleArchive = new TextAsset(archive);
            // Rotations alone at 60 fps: every bone then points along the partner's; with limb IK
            // (144 fps) hands and feet go where the partner's are, scaled, and the elbows and
            // knees bend as the character's proportions need.
            if (fps == 60) partner.retargetFlags = RetargetFlags.NoLimbIk | RetargetFlags.NoFootLock;
            if (fps == 144) Application.streamingAssetsPath = "jar:file:///data/app/com.troupe.sample/base.apk!/assets";
            Call(partner, "Start");
            if ((UnityEngine.Networking.UnityWebRequest.requests - requestsBefore == 1) != (fps == 144))
            {
                Console.WriteLine("FAILED: " + fps + " fps: UnityWebRequest was " + (fps == 144 ? "not " : "") + "used");
                failed = true;
            }
            double worstLimb = 0, worstWrist = 0, sumWrist = 0, sumHips = 0;
            int posed = 0;
            var hipsAtFirst = new UnityEngine.Vector3();
            int maxQueued = 0;
            double gapAtFirst = double.NaN;
            long fedAtFirst = 0;
            double playheadAtFirst = 0;
            var firstShown = new UnityEngine.Vector3();
            bool moved = false;
            var sphere = (Transform[])typeof(TroupePartner)
                .GetField("spheres", BindingFlags.Instance | BindingFlags.NonPublic).GetValue(partner);
            while (now < 60.0)
            {
                // The actor where the clip is at this time (looped), in Unity's axes: Z up
                // right-handed to Y up left-handed is (x, z, y).
                int f = (int)(now * 120.0) % clipFrames;
                for (int j = 0; j < 22; j++)
                {
                    int at = (f * 22 + j) * 3;
                    bones[j].position = new UnityEngine.Vector3(clip[at], clip[at + 2], clip[at + 1]);
                }
                float dt = (float)(1.0 / fps * (0.75 + 0.5 * rng.NextDouble()));
                Time.deltaTime = dt;
                now += dt;
                Call(partner, "Update");
                PosePlayback playback = partner.Playback;
                maxQueued = Math.Max(maxQueued, playback.Queued);
                if (double.IsNaN(gapAtFirst) && playback.Queued > 0)
                {
                    fedAtFirst = partner.FramesFed;
                    playheadAtFirst = playback.Playhead;
                    gapAtFirst = fedAtFirst - playheadAtFirst;
                    if (character == null) firstShown = sphere[0].position;
                    else hipsAtFirst = character[HumanBodyBones.Hips].position;
                }
                else if (!double.IsNaN(gapAtFirst))
                {
                    UnityEngine.Vector3 now_ = character == null ? sphere[0].position : character[HumanBodyBones.Hips].position;
                    UnityEngine.Vector3 then = character == null ? firstShown : hipsAtFirst;
                    if (now_.x != then.x) moved = true;
                    if (character != null)
                    {
                        if (fps == 60) worstLimb = Math.Max(worstLimb, LimbError(character, partner.Shown));
                        else { double w = WristError(character, partner.Shown); worstWrist = Math.Max(worstWrist, w); sumWrist += w; }
                        sumHips += HipMiss(character, partner.Shown);
                        posed++;
                    }
                }
            }
            double gapAtEnd = partner.FramesFed - partner.Playback.Playhead;
            Console.WriteLine(fps + " fps: " + partner.FramesFed + " actor frames fed, playhead "
                + partner.Playback.Playhead.ToString("F1") + ", behind the actor by "
                + gapAtFirst.ToString("F1") + " frames at the first pose and " + gapAtEnd.ToString("F1")
                + " at the end, at most " + maxQueued + " poses held"
                + (character == null ? ", shown as spheres"
                   : fps == 60 ? ", partner character posed " + posed + " times by rotations alone, its limbs within "
                                 + worstLimb.ToString("F2") + " degrees of the partner's"
                   : ", partner character posed " + posed + " times with limb IK, its wrists within "
                     + (100 * worstWrist).ToString("F1") + " cm of the partner's (scaled), "
                     + (100 * sumWrist / Math.Max(1, posed)).ToString("F1") + " cm on average")
                + (character == null ? "" : "; its hips " + (100 * sumHips / Math.Max(1, posed)).ToString("F1")
                   + " cm from the partner's on average"));
            double meanWrist = sumWrist / Math.Max(1, posed), meanHips = sumHips / Math.Max(1, posed);
            if (character != null && (posed == 0 || worstLimb > 1.0 || meanWrist > 0.04 || worstWrist > 0.2 || meanHips > 0.1))
            {
                Console.WriteLine("FAILED: " + fps + " fps: the partner character is off: bones by " + worstLimb
                    + " degrees, wrists by " + meanWrist + " m on average (" + worstWrist + " at most), hips by " + meanHips + " m");
                failed = true;
            }
            if (maxQueued > 10) { Console.WriteLine("FAILED: " + fps + " fps: " + maxQueued + " poses held"); failed = true; }
            if (gapAtEnd - gapAtFirst > Token) { Console.WriteLine("FAILED: " + fps + " fps: the playback fell behind"); failed = true; }
            if (partner.FramesFed < 60 * 30 - 2) { Console.WriteLine("FAILED: " + fps + " fps: the actor was not fed on the clock"); failed = true; }
            if (!moved) { Console.WriteLine("FAILED: " + fps + " fps: the partner did not move"); failed = true; }
            Call(partner, "OnDestroy");
        }
        Console.WriteLine(failed ? "SOME FAILED" : "ALL PASSED");
        return failed ? 1 : 0;
    }
}
